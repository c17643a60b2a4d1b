// Private to tsdf*.cpp: the OpenVDB state behind TsdfVolume (kept out of tsdf.h, which spreads).
#pragma once

#include <openvdb/openvdb.h>

#include <cstdint>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "slam/mapping/tsdf.h"
#include "slam/mapping/tsdf_mesh.h"

namespace certislam::slam {

struct TsdfVolume::Impl {
    TsdfConfig config;
    openvdb::FloatGrid::Ptr sdf;     ///< truncated distance, metres; background +truncation
    openvdb::FloatGrid::Ptr weight;  ///< weight; background 0 (never observed)
    std::unordered_set<openvdb::Coord> dirty_blocks;  ///< leaf origins touched since last mesh
    std::unordered_map<openvdb::Coord, TsdfBlockMesh> mesh_cache;  ///< by leaf origin
    std::size_t last_remeshed = 0;  ///< blocks re-meshed by the last ExtractMesh
    std::string packed;  ///< when packed: SerializeTsdf's bytes in a zstd frame (grids are null)
    TsdfStats packed_stats;  ///< when packed: the sizes at packing, memory = bytes held

    /// Empty grids for `cfg` (calls openvdb::initialize() once per process).
    explicit Impl(const TsdfConfig& cfg);
    /// Marks every allocated leaf dirty (after deserialisation the cache is empty).
    void MarkAllDirty();
    /// True when only the bytes are held (TsdfVolume::Pack).
    bool IsPacked() const { return sdf == nullptr; }
};

struct TsdfVoxelList;

/// The voxels of a packed `im`, decoded without building its grids.
TsdfVoxelList UnpackVoxels(const TsdfVolume::Impl& im);

}  // namespace certislam::slam
