// The table of every team-configuration key (path, type, default, range, meaning): the one source
// for reading configuration files, `certislam config dump` and the README's reference table.
#pragma once

#include <functional>
#include <string>
#include <vector>

namespace YAML {
class Node;
}

namespace certislam::bin {

struct TeamConfig;

/// One key of a team configuration.
struct ConfigKey {
    std::string path;   ///< dotted; "<robot>" stands for a robot id of the team
    std::string type;   ///< integer, number, bool, string, path, choice, list
    std::string range;  ///< values allowed, as text ("" when any)
    std::string doc;    ///< what it does, one line
    std::string kinds;  ///< source kinds it belongs to, space separated ("" for every kind)
    /// The key's value in `config` (robot: the id standing for <robot>), as YAML.
    std::function<std::string(const TeamConfig& config, int robot)> show;
    /// Sets the key in `config`; throws std::invalid_argument with the rule a value breaks.
    std::function<void(const YAML::Node& value, int robot, TeamConfig* config)> read;
};

/// Every key, in the order `config dump` prints them.
const std::vector<ConfigKey>& TeamConfigKeys();

/// The names of source.kind.
const std::vector<std::string>& SourceKindNames();

/// Reads every key of a parsed file into `config` (config->path names the file and resolves
/// relative paths). Throws std::runtime_error "FILE:LINE: KEY.PATH: rule" on an unknown key, a
/// key of another source kind, a wrong type or a value out of range.
void ApplyConfigFile(const YAML::Node& root, TeamConfig* config);

/// What makes `robot`'s mission in `config`, one "key: value" line each (every key of its source
/// kind but where logs go and network addresses, its id and its public key's contents): the
/// identity its durable logs carry.
std::string MissionIdentity(const TeamConfig& config, int robot);

/// A complete configuration for source kind `kind` with every default and a comment per key.
/// Throws std::invalid_argument when `kind` is not a source kind.
std::string DumpConfigYaml(const std::string& kind);

/// The reference table of every key (Markdown), as in the README.
std::string DumpConfigMarkdown();

}  // namespace certislam::bin
