// Voxel-grid downsampling of point clouds (one centroid per occupied voxel), without PCL.
#pragma once

#include "slam/core/keyframe.h"

namespace certislam::slam {

/// The centroid of the points in each occupied cube of side `voxel_m` (> 0), in the order the
/// voxels are first seen; non-finite points are skipped. Same result as PCL's VoxelGrid up to
/// the order of the points, without pulling PCL into every caller.
PointCloud VoxelDownsample(const PointCloud& cloud, double voxel_m);

}  // namespace certislam::slam
