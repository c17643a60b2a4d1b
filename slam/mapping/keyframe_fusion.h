// One mesh of a team's map: every keyframe cloud fused into a single TSDF at given poses.
#pragma once

#include <functional>
#include <vector>

#include "slam/core/keyframe.h"
#include "slam/core/trajectory.h"
#include "slam/mapping/mesh.h"

namespace certislam::slam {

/// Called after each keyframe is integrated with the fraction of keyframes done, in (0, 1].
using FusionProgress = std::function<void(double fraction)>;

/// Integrates the cloud of `robots[r][i]` at pose `trajectories[r][i].T_world_body` (for the
/// keyframes both have) into one TSDF of voxel `voxel_m` (> 0) and returns its mesh, in the
/// trajectories' world frame.
TriangleMesh FuseKeyframes(const std::vector<std::vector<Keyframe>>& robots,
                           const std::vector<Trajectory>& trajectories, double voxel_m,
                           const FusionProgress& progress = {});

}  // namespace certislam::slam
