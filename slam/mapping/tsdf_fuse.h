// Resampling another TSDF's voxels into this one (submap fusion; private to tsdf*.cpp:
// TsdfVolume::FuseVoxels calls it).
#pragma once

#include <Eigen/Geometry>

#include "slam/mapping/tsdf.h"

namespace certislam::slam {

/// Fuses every observed voxel of `src` into `im`: its centre is mapped by `T_this_other` to the
/// nearest voxel of `im` and averaged in by weight.
void FuseTsdfVoxels(TsdfVolume::Impl& im, const TsdfVolume::Impl& src,
                    const Eigen::Isometry3d& T_this_other);

}  // namespace certislam::slam
