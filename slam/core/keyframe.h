// Keyframes and point clouds as every front-end, mapping and system module exchanges them.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <vector>

namespace certislam::slam {

/// A point cloud: points in one frame (named by whoever holds it), metres. float32 xyz,
/// contiguous, so a cloud can travel as one immutable buffer without conversion.
using PointCloud = std::vector<Eigen::Vector3f>;

/// A shared, immutable cloud: moved between stages by handle, never copied.
using PointCloudPtr = std::shared_ptr<const PointCloud>;

/// One keyframe: a deskewed scan in the sensor frame and the odometry pose it was taken at.
struct Keyframe {
    int robot = 0;              ///< robot id
    int index = 0;              ///< keyframe index within the robot, from 0, consecutive
    std::int64_t stamp_ns = 0;  ///< scan time, nanoseconds
    Eigen::Isometry3d T_odom_sensor = Eigen::Isometry3d::Identity();  ///< odometry pose
    PointCloudPtr cloud;  ///< points in the sensor frame
};

}  // namespace certislam::slam
