// A robot node's publications over ROS.
#include "bin/ros/node_publish.h"

#include "bin/verdict.h"

namespace certislam::bin {

std::optional<Eigen::Isometry3d> TeamFromOdom(const slam::Trajectory& trajectory,
                                              const std::vector<Eigen::Isometry3d>& odometry) {
    const std::size_t n = std::min(trajectory.size(), odometry.size());
    if (n == 0) return std::nullopt;
    return trajectory[n - 1].T_world_body * odometry[n - 1].inverse();
}

std::vector<actors::LoopSegment> LoopSegments(const std::vector<slam::LoopClosure>& loops,
                                              const slam::Trajectory& trajectory, int robot) {
    std::vector<actors::LoopSegment> out;
    const auto pose = [&](const slam::PoseId& id) -> const Eigen::Isometry3d* {
        if (id.robot != robot || id.index < 0) return nullptr;
        const auto i = static_cast<std::size_t>(id.index);
        return i < trajectory.size() ? &trajectory[i].T_world_body : nullptr;
    };
    for (const slam::LoopClosure& loop : loops) {
        if (const Eigen::Isometry3d* T_map_a = pose(loop.a)) {
            out.push_back({T_map_a->translation(), (*T_map_a * loop.T_a_b).translation()});
        } else if (const Eigen::Isometry3d* T_map_b = pose(loop.b)) {
            out.push_back(
                {(*T_map_b * loop.T_a_b.inverse()).translation(), T_map_b->translation()});
        }
    }
    return out;
}

NodePublisher::NodePublisher(const RosNodeConfig& config, actors::RosBridge& bridge,
                             actors::LiveKeyframes& live, actors::RobotNode& node,
                             const actors::LoopWatcherActor& loops, int robot, double mesh_voxel_m)
    : config_(config),
      bridge_(bridge),
      live_(live),
      node_(node),
      loops_(loops),
      robot_(robot),
      mesh_voxel_m_(mesh_voxel_m),
      next_mesh_(std::chrono::steady_clock::now()) {}

nlohmann::json NodePublisher::MakeStatus(const actors::SolverSnapshot& s) {
    const actors::LiveIngestStats in = live_.Stats();
    nlohmann::json j{{"robot", robot_},
                     {"stamp_ns", bridge_.NowNs()},
                     {"poses", s.trajectory.size()},
                     {"final", s.final},
                     {"done", node_.Done()},
                     {"inter_robot_loops", s.inter_robot_loops},
                     {"anchor", s.anchor},
                     {"rank", s.rank},
                     {"keyframes",
                      {{"clouds", in.clouds},
                       {"odometry", in.odometry},
                       {"unpaired", in.unpaired},
                       {"out_of_order", in.out_of_order},
                       {"selected", in.selected},
                       {"dropped", in.dropped},
                       {"queued", in.queued},
                       {"handed_out", in.handed_out},
                       {"ended", in.ended}}},
                     {"paths_published", paths_}};
    j["verdict"] = s.report ? VerdictName(s.report->verdict()) : "none";
    j["lambda_min"] = s.report ? nlohmann::json(s.report->lambda_min()) : nlohmann::json();
    j["objective"] = s.report ? nlohmann::json(s.report->objective()) : nlohmann::json();
    // Only a proven bound (S + eta D PSD on the certificate's graph): null otherwise.
    const bool proven = s.report && s.report->has_bound();
    j["lower_bound"] = proven ? nlohmann::json(s.report->lower_bound()) : nlohmann::json();
    j["relative_suboptimality_bound"] =
        proven ? nlohmann::json(s.report->relative_suboptimality_bound()) : nlohmann::json();
    j["lio_sam"] = nullptr;
    if (in.last_message_stamp_ns && in.silent_s > config_.silence_warning_s) {
        j["lio_sam"] = "LIO-SAM silent since " +
                       std::to_string(static_cast<double>(*in.last_message_stamp_ns) * 1e-9) +
                       " (" + std::to_string(static_cast<int>(in.silent_s)) +
                       " s wall): keeping the last solution";
    } else if (!in.last_message_stamp_ns) {
        j["lio_sam"] = "no LIO-SAM message yet";
    }
    const std::string error = bridge_.LastError();
    if (!error.empty()) j["last_input_error"] = error;
    return j;
}

void NodePublisher::Tick() {
    const actors::SolverSnapshot s = node_.Snapshot();
    const std::vector<slam::LoopClosure> loops = loops_.Loops();
    if (s.steps != last_steps_ || loops.size() != last_loops_ ||
        s.inter_robot_loops != last_solver_loops_) {
        last_steps_ = s.steps;
        last_solver_loops_ = s.inter_robot_loops;
        last_loops_ = loops.size();
        if (!s.trajectory.empty()) {
            bridge_.PublishPath(s.trajectory);
            ++paths_;
        }
        bridge_.PublishLoops(LoopSegments(loops, s.trajectory, robot_));
    }
    if (const auto T = TeamFromOdom(s.trajectory, live_.HandedOut())) bridge_.PublishTransform(*T);
    status_ = MakeStatus(s);
    bridge_.PublishStatus(status_.dump());
    actors::MapperActor* mapper = node_.Mapper();
    const auto now = std::chrono::steady_clock::now();
    if (mapper && config_.mesh_period_s > 0.0 && now >= next_mesh_) {
        next_mesh_ = now + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                               std::chrono::duration<double>(config_.mesh_period_s));
        bridge_.PublishMesh(mapper->FusedMesh(mesh_voxel_m_));
    }
}

}  // namespace certislam::bin
