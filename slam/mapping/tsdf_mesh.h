// Marching cubes over a TSDF's 8^3 leaf blocks, cached per block and welded into one mesh
// (private to tsdf*.cpp: TsdfVolume::ExtractMesh calls it).
#pragma once

#include <openvdb/openvdb.h>

#include <cstdint>
#include <unordered_map>
#include <vector>

#include "slam/mapping/mesh.h"
#include "slam/mapping/tsdf.h"

namespace certislam::slam {

/// The mesh of one 8^3 leaf block: its cubes' triangles, and for each vertex the key of the
/// grid edge it lies on (so blocks can be welded into one indexed mesh).
struct TsdfBlockMesh {
    std::vector<std::uint64_t> edge_keys;    ///< one per vertex (see EdgeKey in tsdf_mesh.cpp)
    std::vector<Eigen::Vector3f> vertices;   ///< volume frame, metres
    std::vector<Eigen::Vector3i> triangles;  ///< indices into `vertices`
};

/// Marching cubes over one leaf block of `impl` at `origin`.
TsdfBlockMesh MeshBlock(const TsdfVolume::Impl& impl, const openvdb::Coord& origin);

/// Welds block meshes, given in increasing origin order, into one indexed mesh (a vertex on a grid
/// edge two blocks share is kept once), so a volume meshed in pieces gives ExtractTsdfMesh's mesh.
class TsdfMeshWelder {
  public:
    /// Appends the mesh of the next block.
    void Add(const TsdfBlockMesh& block);
    /// The welded mesh so far (the welder is left empty).
    TriangleMesh Take();
    /// The same with each vertex's edge key: a piece that another welder can Add after the
    /// pieces before it, to give the mesh of all their blocks welded in order.
    TsdfBlockMesh TakeKeyed();

  private:
    TriangleMesh mesh_;
    std::vector<std::uint64_t> keys_;                  // mesh vertex -> edge key
    std::unordered_map<std::uint64_t, int> index_of_;  // edge key -> vertex index
    std::vector<int> global_;                          // block vertex -> mesh vertex
};

/// Re-meshes the blocks of `impl` touched since the last call (and their neighbours), updates
/// its mesh cache and returns the welded mesh of every cached block (TsdfVolume::ExtractMesh).
TriangleMesh ExtractTsdfMesh(TsdfVolume::Impl& impl);

}  // namespace certislam::slam
