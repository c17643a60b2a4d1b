// Stamped pose trajectories as the evaluation, I/O and mission modules exchange them.
#pragma once

#include <Eigen/Geometry>
#include <vector>

namespace certislam::slam {

/// One pose of a trajectory: T_world_body at a time stamp.
struct StampedPose {
    double stamp_s = 0.0;                                            ///< time, seconds
    Eigen::Isometry3d T_world_body = Eigen::Isometry3d::Identity();  ///< pose in the world frame
};

/// A trajectory: poses in stamp order (readers keep file order; KITTI stamps are frame indices).
using Trajectory = std::vector<StampedPose>;

}  // namespace certislam::slam
