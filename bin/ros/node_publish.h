// What a robot's ROS node publishes as its team converges: the path and TF in the team frame,
// the status (certificate, ingest counters, LIO-SAM silence), loop markers and the mesh.
#pragma once

#include <chrono>
#include <cstdint>
#include <nlohmann/json.hpp>

#include "actors/robot_node.h"
#include "actors/ros/live_keyframes.h"
#include "actors/ros/loop_watcher.h"
#include "actors/ros/ros_bridge.h"
#include "bin/ros/ros_config.h"

namespace certislam::bin {

/// T_map_odom of a robot from its latest keyframe with both a team-frame pose (`trajectory`)
/// and an odometry pose (`odometry`); nullopt before the first.
std::optional<Eigen::Isometry3d> TeamFromOdom(const slam::Trajectory& trajectory,
                                              const std::vector<Eigen::Isometry3d>& odometry);

/// Segments of the loops between their two poses in the team frame; the far end placed by the
/// measurement (T_map_a * T_a_b), since only this robot's poses are known here.
std::vector<actors::LoopSegment> LoopSegments(const std::vector<slam::LoopClosure>& loops,
                                              const slam::Trajectory& trajectory, int robot);

/// Publishes a node's state on each Tick().
class NodePublisher {
  public:
    NodePublisher(const RosNodeConfig& config, actors::RosBridge& bridge,
                  actors::LiveKeyframes& live, actors::RobotNode& node,
                  const actors::LoopWatcherActor& loops, int robot, double mesh_voxel_m);

    /// Publishes path and loops when the solver stepped or the loops changed, TF and status always,
    /// the mesh every mesh period.
    void Tick();
    /// The status as last published.
    const nlohmann::json& Status() const { return status_; }
    /// Paths published so far.
    int PathsPublished() const { return paths_; }

  private:
    nlohmann::json MakeStatus(const actors::SolverSnapshot& s);

    RosNodeConfig config_;
    actors::RosBridge& bridge_;
    actors::LiveKeyframes& live_;
    actors::RobotNode& node_;
    const actors::LoopWatcherActor& loops_;
    int robot_;
    double mesh_voxel_m_;
    std::uint64_t last_steps_ = ~std::uint64_t{0};
    std::chrono::steady_clock::time_point next_mesh_;
    std::size_t last_loops_ = 0;
    int last_solver_loops_ = 0;
    int paths_ = 0;
    nlohmann::json status_;
};

}  // namespace certislam::bin
