// What keyframe teams need beyond team_config.cpp: the check of every actor's settings, and the
// outputs (per robot trajectories in TUM, errors against the source's reference, the JSON report
// and its text, the mapper's mesh).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>

#include "bin/command.h"
#include "bin/config/team_config.h"
#include "bin/verdict.h"
#include "slam/eval/trajectory_metrics.h"
#include "slam/io/trajectory_io.h"
#include "slam/mapping/mesh_io.h"

namespace certislam::bin {
namespace {

using nlohmann::json;

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

/// DIR/robot<K>.tum (the estimate) and, where the source has a reference,
/// DIR/robot<K>.ground_truth.tum.
void WriteRobotTrajectories(const std::string& dir, int robot, const slam::Trajectory& estimate,
                            const TeamSource& source) {
    std::filesystem::create_directories(dir);
    const std::string stem = dir + "/robot" + std::to_string(robot);
    std::string error;
    if (!slam::WriteTrajectory(stem + ".tum", estimate, slam::TrajectoryFormat::kTum, &error)) {
        throw std::runtime_error(error);
    }
    const auto truth = source.Truth(robot);
    if (truth && !slam::WriteTrajectory(stem + ".ground_truth.tum", *truth,
                                        slam::TrajectoryFormat::kTum, &error)) {
        throw std::runtime_error(error);
    }
}

}  // namespace

void CheckActorSettings(const TeamConfig& config) {
    if (config.source.kind == SourceConfig::Kind::kPoseGraph) return;  // ReadTeamConfig did
    try {
        config.source.simulator.Validate();
        config.node.Validate();
    } catch (const std::invalid_argument& e) {
        throw std::runtime_error(config.path + ": " + e.what());
    }
}

TeamConfig LoadTeamConfig(const std::string& path) {
    TeamConfig config = ReadTeamConfig(path);
    CheckActorSettings(config);
    return config;
}

std::string WriteTeamOutputs(const std::string& dir, const std::vector<int>& robots,
                             const std::vector<actors::SolverSnapshot>& snapshots,
                             const TeamSource& source, const actors::PoseGraphTeamResult& team,
                             double seconds, const std::string& report_name,
                             const std::vector<json>& meshes) {
    const std::uint64_t bytes_sent = team.bytes_between_robots;
    json report;
    report["schema_version"] = kSchemaVersion;
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
                   {"staircase_level", s.staircase_level},
                   {"restored_from_log", s.restored}};
        // The robot's synchronous rounds (solver.mode rounds): rounds swept, restarts, proposals
        // it dropped, overlaps a rise ended, converged or gave up
        robot["rounds"] = {{"swept", s.team_rounds},
                           {"restarts", s.restarts},
                           {"rejected_proposals", s.rejected_proposals},
                           {"resends", s.round_resends},
                           {"overlap_ends", s.overlap_ends},
                           {"converged", s.rounds_converged},
                           {"gave_up", s.rounds_gave_up}};
        // The team's second-order finish after rounds that did not converge (none: status "")
        robot["finish"] = {{"status", s.finish_status},
                           {"steps", s.finish.iterations},
                           {"cg_iterations", s.finish.tcg_iterations},
                           {"exchanges", s.finish.exchanges},
                           {"seconds", s.finish_seconds}};
        Evaluate(source, robots[k], s, &robot);
        if (k < meshes.size() && !meshes[k].is_null()) robot["mesh"] = meshes[k];
        report["robots"].push_back(robot);
        if (!dir.empty()) WriteRobotTrajectories(dir, robots[k], s.trajectory, source);
    }
    if (!source.TruthKind().empty()) report["reference"] = source.TruthKind();
    const auto& report_of = snapshots.front().report;
    report["certified"] = report_of && report_of->verdict() == v1::CERTIFICATE_VERDICT_CERTIFIED;
    report["lambda_min"] = report_of ? report_of->lambda_min() : 0.0;
    report["verdict"] = report_of ? VerdictName(report_of->verdict()) : "none";
    if (report_of) {
        report["objective"] = report_of->objective();
        report["duality_gap"] = report_of->duality_gap();
    }
    // Only a proven bound (S + eta D PSD on the certificate's graph): null otherwise.
    const bool proven = report_of && report_of->has_bound();
    report["lower_bound"] = proven ? json(report_of->lower_bound()) : json(nullptr);
    report["relative_suboptimality_bound"] =
        proven ? json(report_of->relative_suboptimality_bound()) : json(nullptr);
    report["suboptimality_bound"] = proven ? json(report_of->suboptimality_bound()) : json(nullptr);
    if (report_of && !report_of->reason().empty()) report["reason"] = report_of->reason();
    if (report_of) report["certificate_path"] = CertificatePathName(report_of->path());
    report["inter_robot_loops"] = loops / 2;  // each loop is known to both of its robots
    report["bytes_sent"] = bytes_sent;
    // The keys of `solve --distributed`: team rounds, bytes by actor and robot, certificate work.
    json by_robot = json::object(), steps = json::object();
    for (const auto& [robot, bytes] : team.bytes_by_robot) by_robot[std::to_string(robot)] = bytes;
    for (const auto& [robot, n] : team.iterations_by_robot) steps[std::to_string(robot)] = n;
    report["bytes_between_robots"] = {
        {"total", bytes_sent}, {"by_actor", team.bytes_by_actor}, {"by_robot", by_robot}};
    report["iterations"] = team.iterations;
    report["iterations_by_robot"] = steps;
    report["certificate_rounds"] = team.certificate_rounds;
    report["lanczos_steps"] = team.lanczos_steps;
    report["bytes_per_keyframe"] = keyframes > 0 ? double(bytes_sent) / keyframes : 0.0;
    report["keyframes_per_second"] = seconds > 0 ? keyframes / seconds : 0.0;
    report["seconds"] = seconds;
    std::string text = report.dump(2);
    if (!dir.empty() && !report_name.empty()) {
        std::ofstream(dir + "/" + report_name) << text << "\n";
    }
    return text;
}

json WriteRobotMesh(actors::RobotNode& node, const actors::RobotNodeConfig& config, int id,
                    const std::string& out_dir) {
    actors::MapperActor* mapper = node.Mapper();
    if (!mapper) return nullptr;
    // Two publish periods: the peers' last re-anchorings (pose-only updates) arrive.
    std::this_thread::sleep_for(2 * config.mapper.publish_period);
    const slam::TriangleMesh mesh = mapper->FusedMesh(config.mapper.map.tsdf.voxel_size_m);
    const actors::MapperStats stats = mapper->Stats();
    json out{{"vertices", mesh.vertices.size()},
             {"triangles", mesh.triangles.size()},
             {"own_submaps", stats.own_submaps},
             {"peer_submaps", stats.peer_submaps},
             {"submap_sends", stats.submap_sends},
             {"pose_only_sends", stats.pose_only_sends},
             {"submap_bytes_sent", stats.submap_bytes_sent},
             {"voxel_memory_bytes", stats.budget.memory_bytes},
             {"coarsenings", stats.budget.coarsenings},
             {"voxel_m_now", stats.budget.voxel_size_m},
             {"skipped_over_budget", stats.budget.skipped_scans}};
    if (out_dir.empty()) return out;
    std::filesystem::create_directories(out_dir);
    const std::string path = out_dir + "/robot" + std::to_string(id) + ".mesh.ply";
    if (const std::string error = slam::WriteMeshPly(path, mesh); !error.empty()) {
        throw std::runtime_error(error);
    }
    out["path"] = path;
    return out;
}

std::string TeamReportText(const std::string& report_json) {
    const json r = json::parse(report_json);
    std::ostringstream out;
    out << "verdict: " << r.value("verdict", "none");
    if (r.contains("certificate_path"))
        out << " (" << r["certificate_path"].get<std::string>() << ")";
    out << ", lambda_min " << r.value("lambda_min", 0.0) << ", " << r.value("seconds", 0.0)
        << " s, " << r.value("bytes_sent", std::uint64_t{0}) << " bytes sent, "
        << r.value("inter_robot_loops", 0) << " inter-robot loops\n";
    if (r.contains("objective")) out << "objective " << r["objective"].get<double>();
    if (r.contains("lower_bound") && !r["lower_bound"].is_null()) {
        out << ", lower bound " << r["lower_bound"].get<double>() << " (relative bound "
            << r["relative_suboptimality_bound"].get<double>() << ")";
    } else if (r.contains("objective")) {
        out << ", no bound proven";
    }
    if (r.contains("objective")) out << "\n";
    for (const auto& robot : r.at("robots")) {
        out << "robot " << robot.value("id", -1) << ": " << robot.value("keyframes", 0)
            << " keyframes, anchor " << robot.value("anchor", -1);
        for (const char* key :
             {"ate_rmse_own_alignment", "ate_rmse_team_frame", "offset_error_m"}) {
            if (robot.contains(key)) out << ", " << key << " " << robot[key].get<double>();
        }
        out << "\n";
    }
    return out.str();
}

}  // namespace certislam::bin
