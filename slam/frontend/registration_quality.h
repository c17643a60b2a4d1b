// Quality of an alignment: fitness, point-to-plane Hessian, degeneracy test and information
// (no PCL in the front end).
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <vector>

#include "slam/core/keyframe.h"
#include "slam/frontend/point_kdtree.h"
#include "slam/frontend/registration.h"

namespace certislam::slam {

/// Fitness, Hessian, degeneracy and information of an alignment already found (used by
/// RegisterScans; exposed for tests and other registration back ends). `source` and `target`
/// are the downsampled clouds; `result.T_target_source` must be set; fills the other fields
/// except status/converged, and returns the status the quality tests give (kAccepted if all
/// pass).
RegistrationResult::Status EvaluateAlignment(const PointCloud& source, const PointCloud& target,
                                             const RegistrationConfig& config,
                                             RegistrationResult& result);

/// EvaluateAlignment with a tree over `target` and its LocalPlaneNormals already computed.
RegistrationResult::Status EvaluateAlignment(const PointCloud& source, const PointCloud& target,
                                             const PointKdTree& target_tree,
                                             const std::vector<Eigen::Vector3d>& target_normals,
                                             const RegistrationConfig& config,
                                             RegistrationResult& result);

/// The unit normal of the points `indices` of `cloud` (at least 3): the smallest-eigenvalue
/// direction of their covariance, the plane of the point-to-plane Hessian.
Eigen::Vector3d PlaneNormal(const PointCloud& cloud, const std::vector<std::size_t>& indices);

/// PlaneNormal of every point's k nearest points (`tree` is over `cloud`).
std::vector<Eigen::Vector3d> LocalPlaneNormals(const PointCloud& cloud, const PointKdTree& tree,
                                               int k);

}  // namespace certislam::slam
