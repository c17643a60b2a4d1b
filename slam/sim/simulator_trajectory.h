// The simulator's trajectories: smooth lane-following paths from street waypoints, and the
// drifting odometry integrated along them.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <random>
#include <vector>

#include "slam/sim/simulator.h"

namespace certislam::slam {

/// A planar path parameterised by arc length: densely sampled positions and headings.
class SimPath {
  public:
    /// Offsets the centreline `waypoints` by `lane_offset_m` to the right of travel, rounds each
    /// corner with a quadratic Bezier starting `corner_cut_m` before it, and samples it densely.
    SimPath(const std::vector<Eigen::Vector2d>& waypoints, double lane_offset_m,
            double corner_cut_m);

    double length() const { return s_.back(); }  ///< total arc length, metres
    /// Position (x, y) and heading (rad) at arc length s (clamped to [0, length]).
    void At(double s, Eigen::Vector2d* position, double* yaw) const;

  private:
    std::vector<Eigen::Vector2d> points_;
    std::vector<double> yaw_;  // unwrapped heading at each sample
    std::vector<double> s_;    // cumulative arc length at each sample
};

/// The true sensor pose on the path at arc length s.
Eigen::Isometry3d PathPose(const SimPath& path, double s, double mount_height_m);

/// Keyframe arc lengths, true poses and drifting odometry poses of one robot.
struct SimRobotTrajectory {
    std::vector<double> s;                    ///< arc length of each keyframe
    std::vector<Eigen::Isometry3d> truth;     ///< T_world_sensor
    std::vector<Eigen::Isometry3d> odometry;  ///< T_odom_sensor, identity at keyframe 0
};

/// Integrates the odometry along `path` at the config's step, with the drift model's biases,
/// and samples it every keyframe_spacing_m (SimOdometryDriftConfig says what drifts how).
SimRobotTrajectory IntegrateTrajectory(const SimPath& path, const SimulatorConfig& config,
                                       std::mt19937_64& rng);

}  // namespace certislam::slam
