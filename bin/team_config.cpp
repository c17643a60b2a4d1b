// JSON configuration of run/robot modes, the simulated source, and the team's outputs.
#include "bin/team_config.h"

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "slam/trajectory_io.h"
#include "slam/trajectory_metrics.h"
#include "transport/curve.h"

namespace certislam::bin {
namespace {

using nlohmann::json;

template <class T>
void Read(const json& object, const char* key, T* value) {
    if (object.contains(key)) *value = object.at(key).get<T>();
}

void ReadSolver(const json& j, actors::RobotNodeConfig* node) {
    Read(j, "rank", &node->solver.solver.rank);
    Read(j, "rel_grad_tol", &node->solver.solver.rbcd.rel_grad_tol);
    Read(j, "odometry_sigma_t_m", &node->solver.solver.noise.odometry_sigma_t_m);
    Read(j, "odometry_sigma_r_rad", &node->solver.solver.noise.odometry_sigma_r_rad);
    int max_staircase = node->certifier.max_staircase_steps;
    Read(j, "max_staircase_steps", &max_staircase);
    node->certifier.max_staircase_steps = max_staircase;
}

void ReadMatcher(const json& j, actors::RobotNodeConfig* node) {
    Read(j, "max_sc_distance", &node->matcher.max_sc_distance);
    Read(j, "query_stride", &node->matcher.query_stride);
    Read(j, "min_intra_gap", &node->matcher.min_intra_gap);
    Read(j, "intra_robot", &node->matcher.intra_robot);
}

void ReadNetwork(const json& j, const std::string& dir, TeamConfig* config) {
    const auto resolve = [&](const std::string& p) {
        return p.empty() || p.front() == '/' ? p : (std::filesystem::path(dir) / p).string();
    };
    for (const auto& [key, value] : j.items()) {
        RobotEndpointConfig robot;
        Read(value, "host", &robot.host);
        Read(value, "base_port", &robot.base_port);
        Read(value, "public_key", &robot.public_key);
        Read(value, "secret_key", &robot.secret_key);
        robot.public_key = resolve(robot.public_key);
        robot.secret_key = resolve(robot.secret_key);
        config->network[std::stoi(key)] = robot;
    }
}

}  // namespace

TeamConfig LoadTeamConfig(const std::string& path) {
    std::ifstream in(path);
    if (!in) throw std::runtime_error(path + ": cannot open");
    TeamConfig config;
    config.path = path;
    try {
        const json j = json::parse(in);
        config.robots = j.at("robots").get<std::vector<int>>();
        const json& source = j.at("source");
        if (source.value("kind", "simulator") != "simulator") {
            throw std::runtime_error("source.kind: only \"simulator\" is supported");
        }
        Read(source, "seed", &config.simulator.seed);
        Read(source, "max_keyframes", &config.max_keyframes);
        Read(j, "log_dir", &config.log_dir);
        Read(source, "keyframe_spacing_m", &config.simulator.keyframe_spacing_m);
        config.simulator.num_robots = static_cast<int>(config.robots.size());
        if (j.contains("solver")) ReadSolver(j.at("solver"), &config.node);
        if (j.contains("matcher")) ReadMatcher(j.at("matcher"), &config.node);
        if (j.contains("network")) {
            ReadNetwork(j.at("network"), std::filesystem::path(path).parent_path().string(),
                        &config);
        }
    } catch (const json::exception& e) {
        throw std::runtime_error(path + ": " + e.what());
    }
    if (config.robots.empty()) throw std::runtime_error(path + ": robots: must not be empty");
    for (size_t k = 0; k < config.robots.size(); ++k) {
        if (config.robots[k] != static_cast<int>(k)) {
            throw std::runtime_error(path + ": robots: must be 0, 1, ..., N-1 (simulator ids)");
        }
    }
    try {
        config.simulator.Validate();
        config.node.Validate();
    } catch (const std::invalid_argument& e) {
        throw std::runtime_error(path + ": " + e.what());
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
    }
    return node;
}

actors::TeamWiring TcpWiring(const TeamConfig& config, int robot) {
    actors::TeamWiring wiring;
    wiring.robot = robot;
    wiring.robots = config.robots;
    const actors::Edge edges[] = {actors::Edge::kDescriptors, actors::Edge::kLoops,
                                  actors::Edge::kClouds,      actors::Edge::kPoses,
                                  actors::Edge::kBundle,      actors::Edge::kCertify};
    bool curve = true;
    for (int r : config.robots) {
        if (!config.network.count(r) || config.network.at(r).base_port <= 0) {
            throw std::runtime_error(config.path + ": network." + std::to_string(r) +
                                     ".base_port: missing or not > 0");
        }
        const RobotEndpointConfig& net = config.network.at(r);
        wiring.addresses[r][actors::Edge::kKeyframes] =
            "inproc://certislam/r" + std::to_string(r) + "/keyframes";
        int port = net.base_port;
        for (const auto edge : edges) {
            wiring.addresses[r][edge] = "tcp://" + net.host + ":" + std::to_string(++port);
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

SimulatedSource::SimulatedSource(const TeamConfig& config)
    : max_keyframes_(config.max_keyframes),
      generator_(std::make_shared<slam::MissionGenerator>(config.simulator)) {}

int SimulatedSource::NumKeyframes(int robot) const {
    const int n = generator_->num_keyframes(robot);
    return max_keyframes_ > 0 ? std::min(n, max_keyframes_) : n;
}

actors::KeyframeSource SimulatedSource::For(int robot) const {
    auto next = std::make_shared<int>(0);
    return [this, robot, next]() -> std::optional<slam::Keyframe> {
        if (*next >= NumKeyframes(robot)) return std::nullopt;
        return generator_->Generate(robot, (*next)++).keyframe;
    };
}

slam::Trajectory SimulatedSource::Truth(int robot) const {
    slam::Trajectory out;
    const Eigen::Isometry3d T_team_world = generator_->T_world_odom(0).inverse();
    for (int i = 0; i < NumKeyframes(robot); ++i) {
        out.push_back({static_cast<double>(generator_->PoseOnly(robot, i).stamp_ns) * 1e-9,
                       T_team_world * generator_->T_world_sensor_truth(robot, i)});
    }
    return out;
}

std::string WriteTeamOutputs(const std::string& dir, const std::vector<int>& robots,
                             const std::vector<actors::SolverSnapshot>& snapshots,
                             const std::vector<slam::Trajectory>& truth, std::uint64_t bytes_sent,
                             double seconds) {
    json report;
    report["robots"] = json::array();
    int keyframes = 0, loops = 0;
    for (size_t k = 0; k < robots.size(); ++k) {
        const auto& s = snapshots[k];
        keyframes += s.num_poses;
        loops += s.inter_robot_loops;
        json robot{{"id", robots[k]},
                   {"keyframes", s.num_poses},
                   {"anchor", s.anchor},
                   {"inter_robot_loops", s.inter_robot_loops},
                   {"staircase_level", s.staircase_level}};
        if (k < truth.size()) {
            const auto pairs = slam::Associate(truth[k], s.trajectory, {});
            const auto errors = slam::EvaluateTeam({pairs}, true);
            robot["ate_rmse_own_alignment"] = errors.ate_rmse;
        }
        report["robots"].push_back(robot);
        if (!dir.empty()) {
            std::filesystem::create_directories(dir);
            std::string error;
            slam::WriteTrajectory(dir + "/robot" + std::to_string(robots[k]) + ".tum", s.trajectory,
                                  slam::TrajectoryFormat::kTum, &error);
        }
    }
    const auto& report_of = snapshots.front().report;
    report["certified"] = report_of && report_of->verdict() == v1::CERTIFICATE_VERDICT_CERTIFIED;
    report["lambda_min"] = report_of ? report_of->lambda_min() : 0.0;
    report["inter_robot_loops"] = loops / 2;  // each loop is known to both of its robots
    report["bytes_sent"] = bytes_sent;
    report["bytes_per_keyframe"] = keyframes > 0 ? double(bytes_sent) / keyframes : 0.0;
    report["keyframes_per_second"] = seconds > 0 ? keyframes / seconds : 0.0;
    report["seconds"] = seconds;
    std::string text = report.dump(2);
    if (!dir.empty()) std::ofstream(dir + "/report.json") << text << "\n";
    return text;
}

}  // namespace certislam::bin
