// Marching cubes per 8^3 leaf block of a TSDF, cached and welded.
//
// Our own marching cubes rather than openvdb::tools::volumeToMesh: volumeToMesh assumes a
// closed level set whose inactive space carries the inside/outside sign, but a TSDF built
// from partial LiDAR views is defined only in a band around observed surfaces, so at the band's
// edge it meets the +truncation background and produces false surfaces. Here a cube is
// polygonised only when its 8 corners were all observed (weight > min_mesh_weight), as in
// VDBFusion, and the work is per leaf block, which makes re-meshing incremental.
#include "slam/mapping/tsdf_mesh.h"

#include <algorithm>
#include <array>

#include "slam/mapping/tsdf_impl.h"

namespace certislam::slam {
namespace {

using Leaf = openvdb::FloatGrid::TreeType::LeafNodeType;
constexpr int kDim = static_cast<int>(Leaf::DIM);  // 8 voxels per leaf edge
constexpr int kSpan = kDim + 1;                    // edge base corners per axis in one block

// A grid edge: its base voxel and axis, 20 bits per coordinate (+-2^19 voxels: 52 km at 0.1 m
// in one submap's frame), 2 bits of axis.
std::uint64_t EdgeKey(const openvdb::Coord& base, int axis) {
    const auto pack = [](int v) { return std::uint64_t(v + (1 << 19)) & 0xFFFFF; };
    return pack(base.x()) << 42 | pack(base.y()) << 22 | pack(base.z()) << 2 | std::uint64_t(axis);
}

openvdb::Coord CornerOffset(int c) { return {c & 1, (c >> 1) & 1, c >> 2}; }

// Reads the 8 corners of the cube at `v` (local offset `local` in the leaf, linear `offset`);
// false when a corner is unobserved. Corners inside the leaf are read directly.
bool ReadCorners(const Leaf& s_leaf, const Leaf& w_leaf,
                 const openvdb::FloatGrid::ConstAccessor& s_acc,
                 const openvdb::FloatGrid::ConstAccessor& w_acc, const openvdb::Coord& v,
                 const openvdb::Coord& local, openvdb::Index offset, float min_w,
                 std::array<float, 8>* s) {
    for (int c = 0; c < 8; ++c) {
        const openvdb::Coord d = CornerOffset(c);
        float w;
        if (local.x() + d.x() < kDim && local.y() + d.y() < kDim && local.z() + d.z() < kDim) {
            const openvdb::Index i = offset + (d.x() << 6) + (d.y() << 3) + d.z();
            w = w_leaf.getValue(i);
            (*s)[c] = s_leaf.getValue(i);
        } else {
            w = w_acc.getValue(v + d);
            (*s)[c] = s_acc.getValue(v + d);
        }
        if (!(w > min_w)) return false;
    }
    return true;
}

}  // namespace

TsdfBlockMesh MeshBlock(const TsdfVolume::Impl& impl, const openvdb::Coord& origin) {
    TsdfBlockMesh out;
    const Leaf* w_leaf = impl.weight->tree().probeConstLeaf(origin);
    const Leaf* s_leaf = impl.sdf->tree().probeConstLeaf(origin);
    if (w_leaf == nullptr || s_leaf == nullptr) return out;
    const auto s_acc = impl.sdf->getConstAccessor();
    const auto w_acc = impl.weight->getConstAccessor();
    const float voxel = static_cast<float>(impl.config.voxel_size_m);
    std::array<int, kSpan * kSpan * kSpan * 3> vertex_of;
    vertex_of.fill(-1);
    std::array<float, 8> s;
    for (auto it = w_leaf->cbeginValueOn(); it; ++it) {
        const openvdb::Coord v = it.getCoord();
        const openvdb::Coord local = v - origin;
        if (!ReadCorners(*s_leaf, *w_leaf, s_acc, w_acc, v, local, it.pos(),
                         impl.config.min_mesh_weight, &s)) {
            continue;
        }
        int case_index = 0;
        for (int c = 0; c < 8; ++c) case_index |= (s[c] < 0.0f ? 1 : 0) << c;
        if (case_index == 0 || case_index == 255) continue;
        auto vertex = [&](int e) {
            const int b = CubeEdgeBase(e), tip = CubeEdgeTip(e), axis = e / 4;
            const openvdb::Coord lb = local + CornerOffset(b);
            const int slot = ((lb.x() * kSpan + lb.y()) * kSpan + lb.z()) * 3 + axis;
            if (vertex_of[slot] < 0) {
                const openvdb::Coord base = v + CornerOffset(b);
                Eigen::Vector3f p(base.x() * voxel, base.y() * voxel, base.z() * voxel);
                p[axis] += voxel * s[b] / (s[b] - s[tip]);  // linear zero crossing
                vertex_of[slot] = static_cast<int>(out.vertices.size());
                out.vertices.push_back(p);
                out.edge_keys.push_back(EdgeKey(base, axis));
            }
            return vertex_of[slot];
        };
        for (const auto& tri : CubeCaseTriangles(case_index)) {
            out.triangles.emplace_back(vertex(tri[0]), vertex(tri[1]), vertex(tri[2]));
        }
    }
    return out;
}

TriangleMesh ExtractTsdfMesh(TsdfVolume::Impl& im) {
    // A voxel's change alters the cubes whose minimum corner is it or its -x/-y/-z neighbours,
    // so a touched block also dirties the 7 blocks on its negative sides.
    std::unordered_set<openvdb::Coord> todo;
    for (const openvdb::Coord& o : im.dirty_blocks) {
        for (int c = 0; c < 8; ++c) {
            const openvdb::Coord d = CornerOffset(c);
            todo.insert(o.offsetBy(-d.x() * kDim, -d.y() * kDim, -d.z() * kDim));
        }
    }
    im.dirty_blocks.clear();
    for (const openvdb::Coord& o : todo) {
        TsdfBlockMesh m = MeshBlock(im, o);
        if (m.triangles.empty()) {
            im.mesh_cache.erase(o);
        } else {
            im.mesh_cache[o] = std::move(m);
        }
    }
    im.last_remeshed = todo.size();

    // Weld the blocks (sorted, so the output does not depend on hash order).
    std::vector<openvdb::Coord> origins;
    origins.reserve(im.mesh_cache.size());
    for (const auto& [o, m] : im.mesh_cache) origins.push_back(o);
    std::sort(origins.begin(), origins.end());
    TsdfMeshWelder welder;
    for (const openvdb::Coord& o : origins) welder.Add(im.mesh_cache.at(o));
    return welder.Take();
}

void TsdfMeshWelder::Add(const TsdfBlockMesh& m) {
    global_.resize(m.vertices.size());
    for (std::size_t i = 0; i < m.vertices.size(); ++i) {
        const auto [it, fresh] =
            index_of_.emplace(m.edge_keys[i], static_cast<int>(mesh_.vertices.size()));
        if (fresh) {
            mesh_.vertices.push_back(m.vertices[i]);
            keys_.push_back(m.edge_keys[i]);
        }
        global_[i] = it->second;
    }
    for (const auto& t : m.triangles) {
        mesh_.triangles.emplace_back(global_[t[0]], global_[t[1]], global_[t[2]]);
    }
}

TriangleMesh TsdfMeshWelder::Take() {
    TriangleMesh out = std::move(mesh_);
    mesh_ = {};
    keys_.clear();
    index_of_.clear();
    return out;
}

TsdfBlockMesh TsdfMeshWelder::TakeKeyed() {
    TsdfBlockMesh out;
    out.edge_keys = std::move(keys_);
    keys_ = {};
    TriangleMesh mesh = Take();
    out.vertices = std::move(mesh.vertices);
    out.triangles = std::move(mesh.triangles);
    return out;
}

}  // namespace certislam::slam
