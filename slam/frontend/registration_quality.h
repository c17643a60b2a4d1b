// Quality of an alignment: fitness, point-to-plane Hessian, degeneracy test and information
// (no PCL here: registration.cpp is the only PCL translation unit).
#pragma once

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

/// EvaluateAlignment with a tree over `target` already built.
RegistrationResult::Status EvaluateAlignment(const PointCloud& source, const PointCloud& target,
                                             const PointKdTree& target_tree,
                                             const RegistrationConfig& config,
                                             RegistrationResult& result);

}  // namespace certislam::slam
