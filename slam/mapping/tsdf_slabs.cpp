// TsdfVolume::FuseAndMesh: parts fused and meshed slab by slab along x, in pieces that a caller
// may run on threads, welded into the mesh of the whole fused volume.
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <utility>
#include <vector>

#include "slam/core/check.h"
#include "slam/mapping/tsdf.h"
#include "slam/mapping/tsdf_fuse.h"
#include "slam/mapping/tsdf_impl.h"
#include "slam/mapping/tsdf_mesh.h"
#include "slam/mapping/tsdf_serialize.h"

namespace certislam::slam {
namespace {

using Impl = TsdfVolume::Impl;
constexpr int kDim = static_cast<int>(openvdb::FloatGrid::TreeType::LeafNodeType::DIM);

// The bounding box of the observed voxels of `im`, live or packed.
openvdb::CoordBBox ActiveBox(const TsdfVolume::Impl& im) {
    if (!im.IsPacked()) return im.weight->evalActiveVoxelBoundingBox();
    openvdb::CoordBBox box;
    UnpackVoxels(im).ForEach([&](const openvdb::Coord& c, float, float) { box.expand(c); });
    return box;
}

// The x indices [lo, hi] of a volume of voxel `voxel` that FuseTsdfVoxels maps `src`'s observed
// voxels to by `T`: the images of their bounding box's corners, widened by one voxel (rounding).
std::pair<int, int> FusedXRange(const TsdfVolume::Impl& src, const Eigen::Isometry3d& T,
                                double voxel) {
    const openvdb::CoordBBox box = ActiveBox(src);
    if (box.empty()) return {1, 0};
    const Eigen::Affine3d A =
        Eigen::Scaling(1.0 / voxel) * T * Eigen::Scaling(src.config.voxel_size_m);
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (int c = 0; c < 8; ++c) {
        const openvdb::Coord& x = (c & 1) ? box.max() : box.min();
        const openvdb::Coord& y = (c & 2) ? box.max() : box.min();
        const openvdb::Coord& z = (c & 4) ? box.max() : box.min();
        const double fx = (A * Eigen::Vector3d(x.x(), y.y(), z.z())).x();
        lo = std::min(lo, fx);
        hi = std::max(hi, fx);
    }
    return {static_cast<int>(std::floor(lo)) - 1, static_cast<int>(std::ceil(hi)) + 1};
}

// One part of a fusion: its state, pose and fused x range [lo, hi] (lo > hi: nothing observed).
struct Part {
    const Impl* impl = nullptr;
    Eigen::Isometry3d T_fused_part;
    std::pair<int, int> range;
    double voxels = 0.0;  // observed voxels
};

// Fuses and meshes the slabs starting at x indices `x0s[first, last)`, each `width` voxels wide,
// into one welded piece. A slab also fuses the first voxel column of the next: the corners of its
// last cubes. A block without a leaf has no observed corner.
TsdfBlockMesh MeshSlabs(const std::vector<Part>& parts, const TsdfConfig& config,
                        const std::vector<int>& x0s, std::size_t first, std::size_t last,
                        int width) {
    TsdfMeshWelder welder;
    // Packed parts are fused from voxel lists (not grids), decoded once for the slabs they span.
    std::map<std::size_t, TsdfVoxelList> unpacked;
    for (std::size_t k = first; k < last; ++k) {
        const int x0 = x0s[k], x1 = x0 + width;
        Impl slab(config);
        for (std::size_t i = 0; i < parts.size(); ++i) {
            const auto [lo, hi] = parts[i].range;
            if (hi < x0) unpacked.erase(i);  // its last slab is behind
            if (hi < x0 || lo > x1) continue;
            const Impl& part = *parts[i].impl;
            if (part.IsPacked()) {
                auto [it, added] = unpacked.try_emplace(i);
                if (added) it->second = UnpackVoxels(part);
                FuseTsdfVoxels(slab, it->second, parts[i].T_fused_part, x0, x1);
            } else {
                FuseTsdfVoxels(slab, part, parts[i].T_fused_part, x0, x1);
            }
        }
        std::vector<openvdb::Coord> origins;
        for (auto it = slab.weight->tree().cbeginLeaf(); it; ++it) {
            if (it->origin().x() < x1) origins.push_back(it->origin());
        }
        std::sort(origins.begin(), origins.end());
        for (const openvdb::Coord& o : origins) {
            const TsdfBlockMesh m = MeshBlock(slab, o);
            if (!m.triangles.empty()) welder.Add(m);
        }
    }
    return welder.TakeKeyed();
}

// Bounds b_0 = 0 <= ... <= b_pieces = work.size() of `pieces` runs of slabs of about equal work.
std::vector<std::size_t> SplitByWork(const std::vector<double>& work, int pieces) {
    double total = 0.0;
    for (double w : work) total += w;
    std::vector<std::size_t> bounds{0};
    double done = 0.0;
    for (std::size_t k = 0; k < work.size(); ++k) {
        done += work[k];
        // Close the run once it holds its share of the work (a slab is never split).
        const double share = total * static_cast<double>(bounds.size()) / pieces;
        if (static_cast<int>(bounds.size()) < pieces && done >= share) bounds.push_back(k + 1);
    }
    while (static_cast<int>(bounds.size()) <= pieces) bounds.push_back(work.size());
    return bounds;
}

}  // namespace

TriangleMesh TsdfVolume::FuseAndMesh(const std::vector<FusePart>& parts, const TsdfConfig& config,
                                     int slab_blocks, int pieces, const RunPieces& run) {
    config.Validate();
    CERTISLAM_CHECK(slab_blocks >= 1 && pieces >= 1);
    std::vector<Part> fused;
    int x_min = std::numeric_limits<int>::max(), x_max = std::numeric_limits<int>::min();
    for (const FusePart& p : parts) {
        const Impl& impl = *p.volume->impl_;
        fused.push_back({&impl, p.T_fused_part,
                         FusedXRange(impl, p.T_fused_part, config.voxel_size_m),
                         static_cast<double>(p.volume->Stats().active_voxels)});
        if (fused.back().range.first > fused.back().range.second) continue;
        x_min = std::min(x_min, fused.back().range.first);
        x_max = std::max(x_max, fused.back().range.second);
    }
    // Slabs start on block edges, so each block is meshed whole in one slab, and in the order
    // ExtractMesh welds them (origins sorted, x first). A slab's work, estimated: the voxels of
    // the parts it overlaps (FuseTsdfVoxels skips only their leaves that map outside it).
    const int width = slab_blocks * kDim;
    std::vector<int> x0s;
    std::vector<double> work;
    for (int x0 = x_min & ~(kDim - 1); x_min <= x_max && x0 <= x_max; x0 += width) {
        x0s.push_back(x0);
        work.push_back(0.0);
        for (std::size_t i = 0; i < fused.size(); ++i) {
            if (fused[i].range.second < x0 || fused[i].range.first > x0 + width) continue;
            work.back() += fused[i].voxels;
        }
    }
    pieces =
        std::max(1, std::min(pieces, static_cast<int>(x0s.size())));  // no more runs than slabs
    const std::vector<std::size_t> bounds = SplitByWork(work, pieces);
    std::vector<TsdfBlockMesh> meshed(pieces);
    const auto piece = [&](int k) {
        meshed[k] = MeshSlabs(fused, config, x0s, bounds[k], bounds[k + 1], width);
    };
    if (run) {
        run(pieces, piece);
    } else {
        for (int k = 0; k < pieces; ++k) piece(k);
    }
    TsdfMeshWelder welder;
    for (TsdfBlockMesh& m : meshed) {
        welder.Add(m);
        m = {};  // one copy of each piece at a time
    }
    return welder.Take();
}

}  // namespace certislam::slam
