// Resampling another TSDF's voxels into this one (submap fusion; private to tsdf*.cpp:
// TsdfVolume::FuseVoxels calls it).
#pragma once

#include <Eigen/Geometry>
#include <limits>

#include "slam/mapping/tsdf.h"

namespace certislam::slam {

struct TsdfVoxelList;

/// Fuses every observed voxel of `src` into `im`: its centre is mapped by `T_this_other` to the
/// nearest voxel of `im` and averaged in by weight. Only voxels of `im` with x index in
/// [x_lo, x_hi] are written (a slab of the result; the defaults: all).
void FuseTsdfVoxels(TsdfVolume::Impl& im, const TsdfVolume::Impl& src,
                    const Eigen::Isometry3d& T_this_other,
                    int x_lo = std::numeric_limits<int>::min(),
                    int x_hi = std::numeric_limits<int>::max());

/// The same from a decoded voxel list (a packed volume's voxels without building its grids).
void FuseTsdfVoxels(TsdfVolume::Impl& im, const TsdfVoxelList& src,
                    const Eigen::Isometry3d& T_this_other, int x_lo, int x_hi);

}  // namespace certislam::slam
