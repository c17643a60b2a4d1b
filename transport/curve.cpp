// CURVE key pairs, key files, and the ZAP allow-list handler.
#include "transport/curve.h"

#include <sys/stat.h>

#include <array>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <vector>
#include <zmq_addon.hpp>

namespace certislam::transport {

namespace {

constexpr std::size_t kZ85KeyLength = 40;
constexpr std::size_t kBinaryKeyLength = 32;
constexpr const char* kZapEndpoint = "inproc://zeromq.zap.01";

std::string ReadKeyLine(const std::string& path, const std::string& want_tag) {
    std::ifstream in(path);
    if (!in) throw std::runtime_error(path + ": cannot open key file");
    std::string line;
    int number = 0;
    while (std::getline(in, line)) {
        ++number;
        std::istringstream fields(line);
        std::string first, second;
        fields >> first >> second;
        if (first.empty() || first[0] == '#') continue;
        std::string key;
        if (second.empty() && want_tag == "public") {
            key = first;  // a .pub file: the key alone
        } else if (first == want_tag) {
            key = second;
        } else {
            continue;
        }
        if (!IsValidZ85Key(key)) {
            std::string why = path;
            why += ':';
            why += std::to_string(number);  // not ":" + string: GCC 12 -Wrestrict false positive
            why += ": '";
            why += key;
            why += "' is not a 40-character Z85 key";
            throw std::runtime_error(why);
        }
        return key;
    }
    throw std::runtime_error(path + ": no " + want_tag + " key found");
}

}  // namespace

KeyPair GenerateKeyPair() {
    std::array<char, kZ85KeyLength + 1> public_key{};
    std::array<char, kZ85KeyLength + 1> secret_key{};
    if (zmq_curve_keypair(public_key.data(), secret_key.data()) != 0) throw zmq::error_t();
    return KeyPair{public_key.data(), secret_key.data()};
}

bool IsValidZ85Key(std::string_view text) {
    if (text.size() != kZ85KeyLength) return false;
    std::array<std::uint8_t, kBinaryKeyLength> binary{};
    const std::string copy(text);
    return zmq_z85_decode(binary.data(), copy.c_str()) != nullptr;
}

void SaveKeyPair(const KeyPair& keys, const std::string& prefix) {
    const std::string pub_path = prefix + ".pub";
    const std::string key_path = prefix + ".key";
    {
        std::ofstream pub(pub_path, std::ios::trunc);
        pub << keys.public_z85 << "\n";
        if (!pub) throw std::runtime_error(pub_path + ": cannot write");
    }
    {
        std::ofstream key(key_path, std::ios::trunc);
        if (!key) throw std::runtime_error(key_path + ": cannot write");
        ::chmod(key_path.c_str(), S_IRUSR | S_IWUSR);
        key << "# certislam CURVE key pair: keep secret\n";
        key << "public " << keys.public_z85 << "\nsecret " << keys.secret_z85 << "\n";
        if (!key) throw std::runtime_error(key_path + ": cannot write");
    }
}

KeyPair LoadKeyPair(const std::string& key_path) {
    return KeyPair{ReadKeyLine(key_path, "public"), ReadKeyLine(key_path, "secret")};
}

std::string LoadPublicKey(const std::string& path) { return ReadKeyLine(path, "public"); }

void CurveConfig::Validate() const {
    auto check = [](const std::string& key, const char* field) {
        if (!IsValidZ85Key(key)) {
            throw std::invalid_argument(std::string("CurveConfig.") + field + " = '" + key +
                                        "': must be a 40-character Z85 key");
        }
    };
    check(own.public_z85, "own.public_z85");
    check(own.secret_z85, "own.secret_z85");
    if (!server) check(server_public_z85, "server_public_z85");
    if (zap_domain.empty()) {
        throw std::invalid_argument("CurveConfig.zap_domain = '': must not be empty");
    }
}

void ApplyCurve(zmq::socket_t& socket, const CurveConfig& curve) {
    curve.Validate();
    socket.set(zmq::sockopt::zap_domain, curve.zap_domain);
    if (curve.server) {
        socket.set(zmq::sockopt::curve_server, 1);
        socket.set(zmq::sockopt::curve_secretkey, curve.own.secret_z85);
    } else {
        socket.set(zmq::sockopt::curve_serverkey, curve.server_public_z85);
        socket.set(zmq::sockopt::curve_publickey, curve.own.public_z85);
        socket.set(zmq::sockopt::curve_secretkey, curve.own.secret_z85);
    }
}

ZapAuthenticator::ZapAuthenticator(zmq::context_t& context,
                                   std::map<std::string, std::uint32_t> allowed)
    : handler_(context, zmq::socket_type::rep),
      stop_rx_(context, zmq::socket_type::pair),
      stop_tx_(context, zmq::socket_type::pair),
      allowed_(std::move(allowed)) {
    for (const auto& [key, robot_id] : allowed_) {
        if (!IsValidZ85Key(key)) {
            throw std::invalid_argument("ZapAuthenticator allow-list: '" + key + "' (robot " +
                                        std::to_string(robot_id) +
                                        ") is not a 40-character Z85 key");
        }
    }
    handler_.set(zmq::sockopt::linger, 0);
    stop_rx_.set(zmq::sockopt::linger, 0);
    stop_tx_.set(zmq::sockopt::linger, 0);
    handler_.bind(kZapEndpoint);
    const std::string stop_address =
        "inproc://certislam.zap.stop." + std::to_string(reinterpret_cast<std::uintptr_t>(this));
    stop_rx_.bind(stop_address);
    stop_tx_.connect(stop_address);
    thread_ = std::thread([this] { Run(); });
}

ZapAuthenticator::~ZapAuthenticator() {
    stop_tx_.send(zmq::str_buffer("stop"), zmq::send_flags::none);
    thread_.join();
}

void ZapAuthenticator::Allow(const std::string& public_z85, std::uint32_t robot_id) {
    std::lock_guard lock(mutex_);
    allowed_[public_z85] = robot_id;
}

void ZapAuthenticator::Revoke(const std::string& public_z85) {
    std::lock_guard lock(mutex_);
    allowed_.erase(public_z85);
}

void ZapAuthenticator::Run() {
    std::array<zmq::pollitem_t, 2> items{
        {{handler_.handle(), 0, ZMQ_POLLIN, 0}, {stop_rx_.handle(), 0, ZMQ_POLLIN, 0}}};
    while (true) {
        zmq::poll(items.data(), items.size(), std::chrono::milliseconds(-1));
        if (items[1].revents & ZMQ_POLLIN) return;
        if (items[0].revents & ZMQ_POLLIN) HandleRequest();
    }
}

// ZAP 1.0 (rfc.zeromq.org/spec/27): request frames version, request id, domain, address,
// identity, mechanism, credentials...; reply version, request id, status, text, user id, metadata.
void ZapAuthenticator::HandleRequest() {
    std::vector<zmq::message_t> request;
    if (!zmq::recv_multipart(handler_, std::back_inserter(request))) return;
    std::string request_id;
    std::string user_id;
    bool ok = false;
    if (request.size() >= 6) {
        request_id = request[1].to_string();
        const std::string mechanism = request[5].to_string();
        if (mechanism == "CURVE" && request.size() >= 7 && request[6].size() == kBinaryKeyLength) {
            std::array<char, kZ85KeyLength + 1> z85{};
            zmq_z85_encode(z85.data(), static_cast<const std::uint8_t*>(request[6].data()),
                           kBinaryKeyLength);
            std::lock_guard lock(mutex_);
            const auto it = allowed_.find(z85.data());
            if (it != allowed_.end()) {
                ok = true;
                user_id = std::to_string(it->second);
            }
        }
    }
    (ok ? accepted_ : denied_).fetch_add(1);
    std::array<zmq::message_t, 6> reply{
        zmq::message_t(std::string_view("1.0")),
        zmq::message_t(request_id),
        zmq::message_t(std::string_view(ok ? "200" : "400")),
        zmq::message_t(std::string_view(ok ? "OK" : "key not allowed")),
        zmq::message_t(user_id),
        zmq::message_t()};
    zmq::send_multipart(handler_, reply);
}

}  // namespace certislam::transport
