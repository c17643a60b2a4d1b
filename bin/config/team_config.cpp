// JSON configuration of run/robot modes, the simulated source, and the team's outputs.
#include "bin/config/team_config.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "slam/eval/trajectory_metrics.h"
#include "slam/io/trajectory_io.h"
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

void ReadCertifier(const json& j, const std::string& path, actors::RobotNodeConfig* node) {
    const std::string mode = j.value("mode", "distributed");
    if (mode != "distributed" && mode != "centralised") {
        throw std::runtime_error(path + ": certifier.mode: \"" + mode +
                                 "\" is not distributed or centralised");
    }
    node->certifier.distributed = mode == "distributed";
    Read(j, "max_krylov", &node->certifier.lanczos.max_krylov);
    Read(j, "tolerance", &node->certifier.lanczos.tolerance);
}

void ReadMatcher(const json& j, actors::RobotNodeConfig* node) {
    Read(j, "max_sc_distance", &node->matcher.max_sc_distance);
    Read(j, "query_stride", &node->matcher.query_stride);
    Read(j, "min_intra_gap", &node->matcher.min_intra_gap);
    Read(j, "intra_robot", &node->matcher.intra_robot);
    Read(j, "place_window", &node->matcher.place_window);
    Read(j, "downsample_replies", &node->matcher.downsample_replies);
    if (j.contains("registration")) {
        const json& r = j.at("registration");
        Read(r, "voxel_m", &node->matcher.registration.voxel_m);
        Read(r, "min_fitness", &node->matcher.registration.min_fitness);
        Read(r, "max_correspondence_m", &node->matcher.registration.max_correspondence_m);
    }
}

void ReadMapping(const json& j, const std::string& path, actors::RobotNodeConfig* node) {
    Read(j, "enabled", &node->mapping);
    Read(j, "voxel_m", &node->mapper.map.tsdf.voxel_size_m);
    Read(j, "submap_distance_m", &node->mapper.map.submap_distance_m);
    Read(j, "share_submaps", &node->mapper.share);
    Read(j, "zstd_level", &node->mapper.zstd_level);
    const std::string team_map = j.value("team_map", "anchor");
    if (team_map == "anchor") {
        node->mapper.team_map = actors::TeamMap::kAnchor;
    } else if (team_map == "all") {
        node->mapper.team_map = actors::TeamMap::kAll;
    } else if (team_map == "none") {
        node->mapper.team_map = actors::TeamMap::kNone;
    } else {
        throw std::runtime_error(path + ": mapping.team_map: \"" + team_map +
                                 "\" is not anchor, all or none");
    }
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

constexpr double kRadToDeg = 180.0 / M_PI;

/// The reference figures of one robot (see WriteTeamOutputs).
void Evaluate(const TeamSource& source, int robot, const actors::SolverSnapshot& s, json* out) {
    const auto truth = source.Truth(robot);
    if (!truth || s.trajectory.empty()) return;
    const auto pairs = slam::Associate(*truth, s.trajectory, {});
    (*out)["ate_rmse_own_alignment"] = slam::EvaluateTeam({pairs}, true).ate_rmse;
    // The trajectory is in its anchor's first-keyframe frame; that frame in the team frame is
    // the anchor's first odometry pose, moved by where the anchor's odometry frame truly is.
    const auto T_team_odom_anchor = source.TrueTeamOdom(s.anchor);
    if (!source.TruthInTeamFrame() || !T_team_odom_anchor) return;
    const Eigen::Isometry3d T_team_sol = *T_team_odom_anchor * source.Odometry(s.anchor, 0);
    slam::Trajectory in_team = s.trajectory;
    for (auto& p : in_team) p.T_world_body = T_team_sol * p.T_world_body;
    (*out)["ate_rmse_team_frame"] =
        slam::EvaluateTeam({slam::Associate(*truth, in_team, {})}, false).ate_rmse;
    const auto T_team_odom_true = source.TrueTeamOdom(robot);
    if (!T_team_odom_true) return;
    double max_t = 0.0, max_r = 0.0;
    const int n = std::min(static_cast<int>(in_team.size()), source.NumKeyframes(robot));
    for (int i = 0; i < n; ++i) {
        // Each keyframe gives one estimate of where the robot's odometry frame is.
        const Eigen::Isometry3d T_team_odom =
            in_team[static_cast<size_t>(i)].T_world_body * source.Odometry(robot, i).inverse();
        max_t =
            std::max(max_t, (T_team_odom.translation() - T_team_odom_true->translation()).norm());
        max_r = std::max(
            max_r, Eigen::AngleAxisd(T_team_odom.linear().transpose() * T_team_odom_true->linear())
                           .angle() *
                       kRadToDeg);
    }
    (*out)["offset_error_m"] = max_t;
    (*out)["offset_error_deg"] = max_r;
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
        if (!j.contains("source")) throw std::runtime_error("source: missing");
        config.source = ReadSourceConfig(j.at("source"), path, config.robots);
        Read(j, "log_dir", &config.log_dir);
        if (j.contains("solver")) ReadSolver(j.at("solver"), &config.node);
        if (j.contains("matcher")) ReadMatcher(j.at("matcher"), &config.node);
        if (j.contains("certifier")) ReadCertifier(j.at("certifier"), path, &config.node);
        if (j.contains("mapping")) ReadMapping(j.at("mapping"), path, &config.node);
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
            throw std::runtime_error(path + ": robots: must be 0, 1, ..., N-1");
        }
    }
    try {
        config.source.simulator.Validate();
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
                                  actors::Edge::kBundle,      actors::Edge::kCertify,
                                  actors::Edge::kMap};
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

std::string WriteTeamOutputs(const std::string& dir, const std::vector<int>& robots,
                             const std::vector<actors::SolverSnapshot>& snapshots,
                             const TeamSource& source, std::uint64_t bytes_sent, double seconds) {
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
        Evaluate(source, robots[k], s, &robot);
        report["robots"].push_back(robot);
        if (!dir.empty()) {
            std::filesystem::create_directories(dir);
            std::string error;
            slam::WriteTrajectory(dir + "/robot" + std::to_string(robots[k]) + ".tum", s.trajectory,
                                  slam::TrajectoryFormat::kTum, &error);
        }
    }
    if (!source.TruthKind().empty()) report["reference"] = source.TruthKind();
    const auto& report_of = snapshots.front().report;
    report["certified"] = report_of && report_of->verdict() == v1::CERTIFICATE_VERDICT_CERTIFIED;
    report["lambda_min"] = report_of ? report_of->lambda_min() : 0.0;
    report["verdict"] = report_of ? v1::CertificateVerdict_Name(report_of->verdict()) : "none";
    if (report_of) report["duality_gap"] = report_of->duality_gap();
    if (report_of) report["certificate_path"] = v1::CertificatePath_Name(report_of->path());
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
