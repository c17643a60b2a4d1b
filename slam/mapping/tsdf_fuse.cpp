// Resampling another TSDF's voxels into this one (submap fusion).
#include "slam/mapping/tsdf_fuse.h"

#include <algorithm>
#include <cmath>

#include "slam/mapping/tsdf_impl.h"
#include "slam/mapping/tsdf_serialize.h"

namespace certislam::slam {
namespace {

// Half away from zero, as std::lround, without a library call in every fused voxel's path (x + 0.5
// rounds up at 0.49999999999999994, a value no voxel index takes); |x| is far inside int's range.
int RoundHalfAway(double x) {
    return static_cast<int>(x < 0.0 ? std::ceil(x - 0.5) : std::floor(x + 0.5));
}

// The fusion of the voxels `for_each` visits (for_each(keep_leaf, f) calls f(ijk, sdf, weight)
// for each voxel of the source leaves keep_leaf keeps) of a volume of voxel `src_voxel`, in that
// order (the order fixes the float rounding of the averages).
template <typename ForEach>
void FuseEach(TsdfVolume::Impl& im, double src_voxel, ForEach&& for_each,
              const Eigen::Isometry3d& T_this_other, int x_lo, int x_hi) {
    const double inv_voxel = 1.0 / im.config.voxel_size_m;
    const float max_sdf = static_cast<float>(im.config.truncation_m());
    const Eigen::Affine3d T = Eigen::Scaling(inv_voxel) * T_this_other * Eigen::Scaling(src_voxel);
    // A source leaf whose voxels all map outside [x_lo, x_hi] is skipped whole: their images' x
    // lie within that of the leaf's 8^3 box (T is affine), widened by one for the rounding.
    const Eigen::RowVector3d ax = T.linear().row(0);
    const double reach_lo = 7.0 * ax.cwiseMin(0.0).sum() - 1.0;
    const double reach_hi = 7.0 * ax.cwiseMax(0.0).sum() + 1.0;
    const auto keep_leaf = [&](const openvdb::Coord& o) {
        const double x = ax.dot(Eigen::Vector3d(o.x(), o.y(), o.z())) + T.translation().x();
        return x + reach_hi >= x_lo && x + reach_lo <= x_hi;
    };
    auto s_acc = im.sdf->getAccessor();
    auto w_acc = im.weight->getAccessor();
    openvdb::Coord last_leaf = openvdb::Coord::max();
    for_each(keep_leaf, [&](const openvdb::Coord& c, float src_sdf, float w) {
        const Eigen::Vector3d q = T * Eigen::Vector3d(c.x(), c.y(), c.z());
        const openvdb::Coord ijk(RoundHalfAway(q.x()), RoundHalfAway(q.y()), RoundHalfAway(q.z()));
        if (ijk.x() < x_lo || ijk.x() > x_hi) return;
        const float old_w = w_acc.getValue(ijk);
        const float new_w = old_w + w;
        const float value = std::min(src_sdf, max_sdf);
        s_acc.setValue(ijk, (s_acc.getValue(ijk) * old_w + value * w) / new_w);
        w_acc.setValue(ijk, std::min(new_w, im.config.max_weight));
        const openvdb::Coord leaf = ijk & ~openvdb::Coord::ValueType(7);
        if (leaf != last_leaf) {
            im.dirty_blocks.insert(leaf);
            last_leaf = leaf;
        }
    });
}

}  // namespace

void FuseTsdfVoxels(TsdfVolume::Impl& im, const TsdfVolume::Impl& src,
                    const Eigen::Isometry3d& T_this_other, int x_lo, int x_hi) {
    const auto src_s = src.sdf->getConstAccessor();
    // Leaf by leaf: the order of the grid's ValueOn walk (a TSDF's weight grid has no tiles).
    auto each = [&](auto&& keep_leaf, auto&& f) {
        for (auto leaf = src.weight->tree().cbeginLeaf(); leaf; ++leaf) {
            if (!keep_leaf(leaf->origin())) continue;
            for (auto it = leaf->cbeginValueOn(); it; ++it) {
                const openvdb::Coord c = it.getCoord();
                f(c, src_s.getValue(c), *it);
            }
        }
    };
    FuseEach(im, src.config.voxel_size_m, each, T_this_other, x_lo, x_hi);
}

void FuseTsdfVoxels(TsdfVolume::Impl& im, const TsdfVoxelList& src,
                    const Eigen::Isometry3d& T_this_other, int x_lo, int x_hi) {
    auto each = [&](auto&& keep_leaf, auto&& f) { src.ForEachIn(keep_leaf, f); };
    FuseEach(im, src.config.voxel_size_m, each, T_this_other, x_lo, x_hi);
}

}  // namespace certislam::slam
