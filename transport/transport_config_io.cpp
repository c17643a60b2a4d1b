// The transport section of a robot's YAML configuration: edges, queue policies and key files.
#include "transport/transport_config_io.h"

#include <yaml-cpp/yaml.h>

#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace certislam::transport {

namespace {

// Resolves names and line numbers of one file for its error messages.
class Reader {
  public:
    Reader(std::string source, std::string base_dir)
        : source_(std::move(source)), base_dir_(std::move(base_dir)) {}

    [[noreturn]] void Fail(const YAML::Node& node, const std::string& message) const {
        const int line = node.Mark().is_null() ? 0 : node.Mark().line + 1;
        throw std::runtime_error(source_ + ":" + std::to_string(line) + ": " + message);
    }

    template <class T>
    T Scalar(const YAML::Node& node, const std::string& field) const {
        if (!node.IsScalar()) Fail(node, field + " must be a single value");
        try {
            return node.as<T>();
        } catch (const YAML::Exception&) {
            Fail(node, field + " = '" + node.Scalar() + "' has the wrong type");
        }
    }

    std::vector<std::string> Addresses(const YAML::Node& node, const std::string& field) const {
        if (node.IsScalar()) return {node.Scalar()};
        if (!node.IsSequence()) Fail(node, field + " must be an address or a list of addresses");
        std::vector<std::string> addresses;
        for (const auto& item : node) addresses.push_back(Scalar<std::string>(item, field));
        return addresses;
    }

    std::string Path(const YAML::Node& node, const std::string& field) const {
        const std::filesystem::path path = Scalar<std::string>(node, field);
        return path.is_absolute() ? path.string() : (base_dir_ / path).string();
    }

    // Runs a key-file loader; its error is reported at the line that names the file.
    template <class F>
    auto KeyFile(const YAML::Node& node, const std::string& field, F load) const {
        const std::string path = Path(node, field);
        try {
            return load(path);
        } catch (const std::runtime_error& e) {
            Fail(node, field + ": " + e.what());
        }
    }

  private:
    std::string source_;
    std::filesystem::path base_dir_;
};

Role ParseRole(const Reader& reader, const YAML::Node& node) {
    static const std::map<std::string, Role> kRoles = {
        {"publisher", Role::kPublisher}, {"subscriber", Role::kSubscriber},
        {"dealer", Role::kDealer},       {"router", Role::kRouter},
        {"push", Role::kPush},           {"pull", Role::kPull}};
    const auto name = reader.Scalar<std::string>(node, "role");
    const auto it = kRoles.find(name);
    if (it == kRoles.end()) {
        reader.Fail(node, "role = '" + name +
                              "': must be publisher, subscriber, dealer, router, push or pull");
    }
    return it->second;
}

Delivery ParseDelivery(const Reader& reader, const YAML::Node& node) {
    const auto name = reader.Scalar<std::string>(node, "delivery");
    if (name == "latest") return Delivery::kLatest;
    if (name == "reliable") return Delivery::kReliable;
    reader.Fail(node, "delivery = '" + name + "': must be latest or reliable");
}

CurveConfig ParseCurve(const Reader& reader, const YAML::Node& edge,
                       const TransportFileConfig& file) {
    const YAML::Node node = edge["curve"];
    const auto side = reader.Scalar<std::string>(node, "curve");
    if (side != "server" && side != "client") {
        reader.Fail(node, "curve = '" + side + "': must be server or client");
    }
    if (!file.own_keys) reader.Fail(node, "curve needs this robot's keys (keys.own)");
    CurveConfig curve;
    curve.server = side == "server";
    curve.own = *file.own_keys;
    if (!curve.server) {
        if (!edge["server_key"]) reader.Fail(node, "curve: client needs server_key (a .pub file)");
        curve.server_public_z85 =
            reader.KeyFile(edge["server_key"], "server_key",
                           [](const std::string& path) { return LoadPublicKey(path); });
    }
    return curve;
}

// The shared-memory path of ipc:// edges and the kernel socket buffers.
void ParseBuffers(const Reader& reader, const YAML::Node& node, EndpointConfig& config) {
    if (node["shm"]) config.shm_enabled = reader.Scalar<bool>(node["shm"], "shm");
    if (node["shm_threshold_bytes"]) {
        config.shm_threshold_bytes =
            reader.Scalar<std::size_t>(node["shm_threshold_bytes"], "shm_threshold_bytes");
    }
    if (node["shm_pool_segments"]) {
        config.shm_pool_segments =
            reader.Scalar<std::size_t>(node["shm_pool_segments"], "shm_pool_segments");
    }
    if (node["socket_buffer_bytes"]) {
        config.socket_buffer_bytes =
            reader.Scalar<int>(node["socket_buffer_bytes"], "socket_buffer_bytes");
    }
}

EndpointConfig ParseEdge(const Reader& reader, const std::string& key, const YAML::Node& node,
                         const TransportFileConfig& file) {
    static const std::set<std::string> kFields = {"role",
                                                  "bind",
                                                  "connect",
                                                  "delivery",
                                                  "max_queue_messages",
                                                  "max_queue_bytes",
                                                  "send_timeout_ms",
                                                  "reconnect_interval_ms",
                                                  "curve",
                                                  "server_key",
                                                  "shm",
                                                  "shm_threshold_bytes",
                                                  "shm_pool_segments",
                                                  "socket_buffer_bytes"};
    if (!node.IsMap()) reader.Fail(node, "edge " + key + " must be a map of fields");
    for (const auto& field : node) {
        const auto name = field.first.Scalar();
        if (kFields.count(name) == 0) {
            std::string message = "edge " + key;
            message += ": unknown field '" + name + "'";
            reader.Fail(field.first, message);
        }
    }
    EndpointConfig config;
    config.edge = key.substr(0, key.find('/'));
    config.robot_id = file.robot_id;
    config.node_name = file.node_name;
    if (!node["role"]) reader.Fail(node, "edge " + key + ": role is required");
    config.role = ParseRole(reader, node["role"]);
    if (node["bind"]) config.bind = reader.Addresses(node["bind"], "bind");
    if (node["connect"]) config.connect = reader.Addresses(node["connect"], "connect");
    if (node["delivery"]) config.delivery = ParseDelivery(reader, node["delivery"]);
    if (node["max_queue_messages"]) {
        config.max_queue_messages =
            reader.Scalar<std::size_t>(node["max_queue_messages"], "max_queue_messages");
    }
    if (node["max_queue_bytes"]) {
        config.max_queue_bytes =
            reader.Scalar<std::size_t>(node["max_queue_bytes"], "max_queue_bytes");
    }
    if (node["send_timeout_ms"]) {
        config.send_timeout_ms = reader.Scalar<int>(node["send_timeout_ms"], "send_timeout_ms");
    }
    if (node["reconnect_interval_ms"]) {
        config.reconnect_interval_ms =
            reader.Scalar<int>(node["reconnect_interval_ms"], "reconnect_interval_ms");
    }
    if (node["curve"]) config.curve = ParseCurve(reader, node, file);
    ParseBuffers(reader, node, config);
    try {
        config.Validate();
    } catch (const std::invalid_argument& e) {
        reader.Fail(node, e.what());
    }
    return config;
}

void ParseKeys(const Reader& reader, const YAML::Node& keys, TransportFileConfig& file) {
    if (!keys.IsMap()) reader.Fail(keys, "keys must be a map (own, allow)");
    if (keys["own"]) {
        file.own_keys = reader.KeyFile(keys["own"], "keys.own",
                                       [](const std::string& path) { return LoadKeyPair(path); });
    }
    if (!keys["allow"]) return;
    if (!keys["allow"].IsMap()) reader.Fail(keys["allow"], "keys.allow must map robot id -> .pub");
    for (const auto& entry : keys["allow"]) {
        const auto robot = reader.Scalar<std::uint32_t>(entry.first, "keys.allow robot id");
        const std::string key =
            reader.KeyFile(entry.second, "keys.allow",
                           [](const std::string& path) { return LoadPublicKey(path); });
        if (!file.allow_list.emplace(key, robot).second) {
            reader.Fail(entry.second, "keys.allow: the same public key is listed twice");
        }
    }
}

}  // namespace

TransportFileConfig ParseTransportConfig(const std::string& yaml_text, const std::string& base_dir,
                                         const std::string& source) {
    const Reader reader(source, base_dir);
    YAML::Node root;
    try {
        root = YAML::Load(yaml_text);
    } catch (const YAML::Exception& e) {
        throw std::runtime_error(source + ":" + std::to_string(e.mark.line + 1) + ": " + e.msg);
    }
    TransportFileConfig file;
    if (!root.IsMap()) reader.Fail(root, "the configuration must be a map");
    if (root["robot_id"])
        file.robot_id = reader.Scalar<std::uint32_t>(root["robot_id"], "robot_id");
    if (root["node_name"]) {
        file.node_name = reader.Scalar<std::string>(root["node_name"], "node_name");
    }
    if (root["keys"]) ParseKeys(reader, root["keys"], file);
    if (!root["edges"]) return file;
    if (!root["edges"].IsMap()) reader.Fail(root["edges"], "edges must map edge/role -> fields");
    for (const auto& entry : root["edges"]) {
        const auto key = entry.first.Scalar();
        if (file.edges.Has(key)) reader.Fail(entry.first, "edge " + key + " is listed twice");
        file.edges.Add(key, ParseEdge(reader, key, entry.second, file));
    }
    return file;
}

TransportFileConfig LoadTransportConfig(const std::string& path) {
    std::ifstream in(path);
    if (!in) throw std::runtime_error(path + ": cannot open the configuration file");
    std::stringstream text;
    text << in.rdbuf();
    return ParseTransportConfig(text.str(), std::filesystem::path(path).parent_path().string(),
                                path);
}

}  // namespace certislam::transport
