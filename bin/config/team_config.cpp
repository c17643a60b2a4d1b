// Team configuration files: reading (with the file, line and key in every error), each robot's
// node settings and its wiring as a process of its own. What a back-end-only robot needs of them
// (bin/robot_main.cpp); the reports and meshes of keyframe teams are in team_outputs.cpp.
#include "bin/config/team_config.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <stdexcept>

#include "actors/durable_log.h"
#include "bin/config/config_keys.h"
#include "transport/curve.h"

namespace certislam::bin {
namespace {

constexpr size_t kMaxIpcPath = 107;  ///< sockaddr_un's sun_path without its NUL

}  // namespace

TeamConfig ReadTeamConfig(const std::string& path) {
    std::ifstream in(path);
    if (!in) throw std::runtime_error(path + ": cannot open");
    TeamConfig config;
    config.path = path;
    YAML::Node root;
    try {
        root = YAML::Load(in);
    } catch (const YAML::ParserException& e) {
        throw std::runtime_error(path + ":" + std::to_string(e.mark.line + 1) + ": " + e.msg);
    }
    ApplyConfigFile(root, &config);
    config.node.quiet = std::chrono::milliseconds(std::llround(config.quiet_s * 1000.0));
    if (!root["robots"]) throw std::runtime_error(path + ": robots: missing");
    if (!root["source"]) throw std::runtime_error(path + ": source: missing");
    FinishSourceConfig(path, config.robots, &config.source);
    for (const auto& [r, net] : config.network) {
        if (std::find(config.robots.begin(), config.robots.end(), r) == config.robots.end()) {
            throw std::runtime_error(path + ": network." + std::to_string(r) +
                                     ": robot not in the team");
        }
    }
    if (config.source.kind == SourceConfig::Kind::kPoseGraph) {
        try {
            PoseGraphNodeConfigFrom(config.node).Validate();
        } catch (const std::invalid_argument& e) {
            throw std::runtime_error(path + ": " + e.what());
        }
    }
    return config;
}

actors::RobotNodeConfig NodeConfigFor(const TeamConfig& config, int robot) {
    actors::RobotNodeConfig node = config.node;
    if (!config.log_dir.empty()) {
        std::filesystem::create_directories(config.log_dir);
        const std::string prefix = config.log_dir + "/robot" + std::to_string(robot);
        node.ingest.log_path = prefix + ".keyframes.log";
        node.solver.log_path = prefix + ".loops.log";
        const std::string identity = MissionIdentity(config, robot);
        node.ingest.log_identity = identity;
        node.solver.log_identity = identity;
        for (const std::string& log : {node.ingest.log_path, node.solver.log_path}) {
            const actors::DurableLogCheck check =
                actors::PrepareDurableLog(log, identity, config.log_stale);
            if (!check.moved_to.empty()) {
                std::fprintf(stderr, "certislam: %s was stale or corrupt: moved to %s\n",
                             log.c_str(), check.moved_to.c_str());
            }
        }
    }
    return node;
}

actors::PoseGraphNodeConfig PoseGraphNodeConfigFrom(const actors::RobotNodeConfig& node) {
    actors::PoseGraphNodeConfig pose_graph;
    pose_graph.solver = node.solver;
    pose_graph.solver.synchronous = true;
    pose_graph.solver.async_until_final = false;
    pose_graph.solver.rounds = actors::PoseGraphNodeConfig{}.solver.rounds;
    pose_graph.solver.rounds.overlap_depth = node.solver.rounds.overlap_depth;
    pose_graph.solver.rounds.max_rounds = node.solver.rounds.max_rounds;
    pose_graph.certifier = node.certifier;
    pose_graph.quiet = node.quiet;
    return pose_graph;
}

actors::TeamWiring NetworkWiring(const TeamConfig& config, int robot) {
    actors::TeamWiring wiring;
    wiring.robot = robot;
    wiring.robots = config.robots;
    const actors::Edge edges[] = {actors::Edge::kDescriptors, actors::Edge::kLoops,
                                  actors::Edge::kClouds,      actors::Edge::kPoses,
                                  actors::Edge::kBundle,      actors::Edge::kCertify,
                                  actors::Edge::kMap};
    bool curve = true;
    for (int r : config.robots) {
        const std::string key = "network." + std::to_string(r);
        const auto it = config.network.find(r);
        if (it == config.network.end() ||
            (it->second.base_port <= 0 && it->second.ipc_dir.empty())) {
            throw std::runtime_error(config.path + ": " + key +
                                     ".base_port: missing or not > 0 (or give ipc_dir)");
        }
        const RobotEndpointConfig& net = it->second;
        wiring.addresses[r][actors::Edge::kKeyframes] =
            "inproc://certislam/r" + std::to_string(r) + "/keyframes";
        int port = net.base_port;
        for (const auto edge : edges) {
            wiring.addresses[r][edge] = net.ipc_dir.empty()
                                            ? "tcp://" + net.host + ":" + std::to_string(++port)
                                            : "ipc://" + net.ipc_dir + "/r" + std::to_string(r) +
                                                  "." + actors::EdgeName(edge);
        }
        // sockaddr_un holds 107 bytes of path: a longer one would be cut silently.
        if (!net.ipc_dir.empty() &&
            net.ipc_dir.size() + std::to_string(r).size() + 16 > kMaxIpcPath) {
            throw std::runtime_error(config.path + ": " + key + ".ipc_dir: \"" + net.ipc_dir +
                                     "\" is too long for a Unix socket path (at most " +
                                     std::to_string(kMaxIpcPath - 16) + " characters)");
        }
        curve = curve && !net.public_key.empty();
        if (!net.public_key.empty())
            wiring.public_keys[r] = transport::LoadPublicKey(net.public_key);
    }
    if (curve) {
        const std::string& secret = config.network.at(robot).secret_key;
        if (secret.empty()) {
            throw std::runtime_error(config.path + ": network." + std::to_string(robot) +
                                     ".secret_key: needed with CURVE");
        }
        wiring.own_keys = transport::LoadKeyPair(secret);
    } else {
        wiring.public_keys.clear();
    }
    wiring.Validate();
    return wiring;
}

}  // namespace certislam::bin
