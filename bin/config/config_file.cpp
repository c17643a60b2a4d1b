// Reading a configuration file against the key table, and printing the table as a complete YAML
// configuration or as the README's Markdown reference.
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <fstream>
#include <iterator>
#include <sstream>
#include <stdexcept>

#include "bin/config/config_keys.h"
#include "bin/config/team_config.h"

namespace certislam::bin {
namespace {

constexpr const char* kRobot = "<robot>";

std::string Join(const std::string& prefix, const std::string& name) {
    return prefix.empty() ? name : prefix + "." + name;
}

bool StartsWith(const std::string& s, const std::string& prefix) {
    return s.compare(0, prefix.size(), prefix) == 0;
}

bool InKind(const ConfigKey& key, const std::string& kind) {
    if (key.kinds.empty()) return true;
    std::istringstream kinds(key.kinds);
    std::string k;
    while (kinds >> k) {
        if (k == kind) return true;
    }
    return false;
}

/// Keys at `pattern` or below it.
std::vector<const ConfigKey*> Under(const std::string& pattern) {
    std::vector<const ConfigKey*> out;
    for (const auto& key : TeamConfigKeys()) {
        if (key.path == pattern || StartsWith(key.path, pattern + ".")) out.push_back(&key);
    }
    return out;
}

size_t EditDistance(const std::string& a, const std::string& b) {
    std::vector<size_t> row(b.size() + 1);
    for (size_t j = 0; j <= b.size(); ++j) row[j] = j;
    for (size_t i = 1; i <= a.size(); ++i) {
        size_t diagonal = row[0];
        row[0] = i;
        for (size_t j = 1; j <= b.size(); ++j) {
            const size_t up = row[j];
            row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] != b[j - 1])});
            diagonal = up;
        }
    }
    return row[b.size()];
}

/// "; did you mean 'x'?" for the closest key next to an unknown `name` under `prefix`.
std::string Suggestion(const std::string& prefix, const std::string& name) {
    std::string best;
    size_t best_distance = 4;
    for (const auto& key : TeamConfigKeys()) {
        if (!prefix.empty() && !StartsWith(key.path, prefix + ".")) continue;
        const std::string rest = key.path.substr(prefix.empty() ? 0 : prefix.size() + 1);
        const std::string sibling = rest.substr(0, rest.find('.'));
        const size_t d = EditDistance(name, sibling);
        if (d < best_distance) best_distance = d, best = sibling;
    }
    return best.empty() ? "" : " (did you mean '" + best + "'?)";
}

class FileReader {
  public:
    FileReader(TeamConfig* config, std::string kind) : config_(config), kind_(std::move(kind)) {}

    [[noreturn]] void Fail(const YAML::Node& node, const std::string& path,
                           const std::string& rule) const {
        const int line = node.Mark().is_null() ? 0 : node.Mark().line + 1;
        throw std::runtime_error(config_->path + ":" + std::to_string(line) + ": " + path + ": " +
                                 rule);
    }

    /// Reads the keys of the mapping `map` at `pattern` (shown to the user as `shown`).
    void Walk(const YAML::Node& map, const std::string& pattern, const std::string& shown,
              int robot) {
        if (map.IsNull()) return;
        if (!map.IsMap()) Fail(map, shown.empty() ? "(top level)" : shown, "must be a mapping");
        for (const auto& item : map) {
            const std::string name = item.first.Scalar();
            // The `ros` section belongs to the ROS node, which checks it itself (bin/ros).
            if (pattern.empty() && name == "ros") continue;
            std::string child = Join(pattern, name);
            int child_robot = robot;
            if (Under(child).empty() && !Under(Join(pattern, kRobot)).empty()) {
                child = Join(pattern, kRobot);
                child_robot = RobotId(item.first, Join(shown, name));
            }
            Visit(item.first, item.second, child, Join(shown, name), child_robot);
        }
    }

  private:
    void Visit(const YAML::Node& key_node, const YAML::Node& value, const std::string& pattern,
               const std::string& shown, int robot) {
        const auto keys = Under(pattern);
        if (keys.empty()) {
            const auto dot = pattern.rfind('.');
            const std::string prefix = dot == std::string::npos ? "" : pattern.substr(0, dot);
            Fail(key_node, shown, "unknown key" + Suggestion(prefix, key_node.Scalar()));
        }
        if (std::none_of(keys.begin(), keys.end(),
                         [&](const ConfigKey* k) { return InKind(*k, kind_); })) {
            Fail(key_node, shown,
                 "belongs to source.kind " + keys.front()->kinds + ", not " + kind_);
        }
        if (keys.front()->path != pattern) return Walk(value, pattern, shown, robot);
        try {
            keys.front()->read(value, robot, config_);
        } catch (const std::invalid_argument& e) {
            Fail(value, shown, e.what());
        }
    }

    int RobotId(const YAML::Node& key, const std::string& shown) const {
        try {
            const int robot = key.as<int>();
            if (robot >= 0) return robot;
        } catch (const YAML::Exception&) {
        }
        Fail(key, shown, "must be a robot id (0, 1, ...)");
    }

    TeamConfig* config_;
    std::string kind_;
};

}  // namespace

void ApplyConfigFile(const YAML::Node& root, TeamConfig* config) {
    // The source kind first: it decides which source keys belong.
    if (root.IsMap() && root["source"] && root["source"].IsMap() && root["source"]["kind"]) {
        const YAML::Node kind = root["source"]["kind"];
        const ConfigKey* key = Under("source.kind").front();
        try {
            key->read(kind, 0, config);
        } catch (const std::invalid_argument& e) {
            FileReader(config, "").Fail(kind, "source.kind", e.what());
        }
    }
    const std::string kind = Under("source.kind").front()->show(*config, 0);
    FileReader(config, kind).Walk(root, "", "", 0);
}

std::string DumpConfigYaml(const std::string& kind) {
    const auto& kinds = SourceKindNames();
    if (std::find(kinds.begin(), kinds.end(), kind) == kinds.end()) {
        throw std::invalid_argument("no source kind '" + kind + "'");
    }
    TeamConfig config;
    config.robots = {0, 1};
    YAML::Node kind_node(kind);
    Under("source.kind").front()->read(kind_node, 0, &config);
    std::ostringstream out;
    out << "# certislam team configuration: every key with its default (source.kind " << kind
        << ").\n# `certislam run FILE` or `certislam robot FILE --id K`; JSON is read too.\n";
    std::vector<std::string> open;  // the mapping keys printed so far, outermost first
    const auto print = [&](const ConfigKey& key, int robot) {
        std::vector<std::string> parts;
        std::istringstream path(key.path);
        for (std::string part; std::getline(path, part, '.');) {
            parts.push_back(part == kRobot ? std::to_string(robot) : part);
        }
        size_t common = 0;
        while (common < open.size() && common + 1 < parts.size() && open[common] == parts[common]) {
            ++common;
        }
        open.resize(common);
        for (size_t i = common; i + 1 < parts.size(); ++i) {
            out << std::string(2 * i, ' ') << parts[i] << ":\n";
            open.push_back(parts[i]);
        }
        std::string line =
            std::string(2 * open.size(), ' ') + parts.back() + ": " + key.show(config, robot);
        line.resize(std::max<size_t>(line.size() + 1, 40), ' ');
        out << line << "# " << key.doc << (key.range.empty() ? "" : "; " + key.range) << "\n";
    };
    // Keys of one robot's entry are printed together, robot by robot.
    const auto& keys = TeamConfigKeys();
    for (size_t i = 0; i < keys.size();) {
        const size_t at = keys[i].path.find(kRobot);
        size_t end = i + 1;
        while (at != std::string::npos && end < keys.size() &&
               keys[end].path.compare(0, at, keys[i].path, 0, at) == 0) {
            ++end;
        }
        for (const int r : at == std::string::npos ? std::vector<int>{0} : config.robots) {
            for (size_t k = i; k < end; ++k) {
                if (InKind(keys[k], kind)) print(keys[k], r);
            }
        }
        i = end;
    }
    return out.str();
}

std::string MissionIdentity(const TeamConfig& config, int robot) {
    const std::string kind = Under("source.kind").front()->show(config, 0);
    std::ostringstream out;
    out << "robot: " << robot << "\n";
    for (const auto& key : TeamConfigKeys()) {
        if (!InKind(key, kind) || StartsWith(key.path, "log_") ||
            StartsWith(key.path, "network.")) {
            continue;
        }
        const bool per_robot = key.path.find(kRobot) != std::string::npos;
        for (const int r : per_robot ? config.robots : std::vector<int>{0}) {
            std::string path = key.path;
            if (per_robot)
                path.replace(path.find(kRobot), std::string(kRobot).size(), std::to_string(r));
            out << path << ": " << key.show(config, r) << "\n";
        }
    }
    const auto own = config.network.find(robot);
    if (own != config.network.end() && !own->second.public_key.empty()) {
        std::ifstream key(own->second.public_key);
        out << "public_key: " << std::string(std::istreambuf_iterator<char>(key), {}) << "\n";
    }
    return out.str();
}

std::string DumpConfigMarkdown() {
    const TeamConfig config;
    std::ostringstream out;
    out << "| key | type | default | range | source kinds | meaning |\n"
        << "|---|---|---|---|---|---|\n";
    for (const auto& key : TeamConfigKeys()) {
        const std::string value = key.path == "robots" ? "" : key.show(config, 0);
        out << "| `" << key.path << "` | " << key.type << " | " << (value.empty() ? "" : "`")
            << value << (value.empty() ? "" : "`") << " | " << key.range << " | "
            << (key.kinds.empty() ? "all" : key.kinds) << " | " << key.doc << " |\n";
    }
    return out.str();
}

}  // namespace certislam::bin
