// Odometry degraded in the simulated city's tunnel: along a featureless tunnel LiDAR odometry
// under-observes the along-track motion, an effect the simulator's drift model does not have.
#pragma once

#include <Eigen/Geometry>
#include <vector>

#include "slam/core/keyframe.h"
#include "slam/sim/sim_world.h"

namespace certislam::slam {

/// Shortens by the fraction `slip` (0 <= slip < 1) the translation of every odometry step
/// whose true midpoint lies inside the tunnel of `streets`, and re-integrates each robot's
/// odometry from its first keyframe. `T_world_sensor_truth[r][i]` is the true pose of
/// `robots[r][i]`. Returns the number of steps degraded.
int DegradeOdometryInTunnel(const SimStreets& streets, double slip,
                            const std::vector<std::vector<Eigen::Isometry3d>>& T_world_sensor_truth,
                            std::vector<std::vector<Keyframe>>* robots);

/// The same on one robot's odometry poses (`T_odom_sensor[i]` of true pose
/// `T_world_sensor_truth[i]`), re-integrated from the first. Returns the steps degraded.
int DegradeOdometryInTunnel(const SimStreets& streets, double slip,
                            const std::vector<Eigen::Isometry3d>& T_world_sensor_truth,
                            std::vector<Eigen::Isometry3d>* T_odom_sensor);

}  // namespace certislam::slam
