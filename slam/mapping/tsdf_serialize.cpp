// A TSDF's lossless compressed bytes (OpenVDB stream, blosc) and voxel-exact comparison.
#include "slam/mapping/tsdf_serialize.h"

#include <openvdb/io/Stream.h>

#include <bit>
#include <cstring>
#include <sstream>

#include "slam/mapping/tsdf_impl.h"

namespace certislam::slam {
namespace {

static_assert(std::endian::native == std::endian::little, "the byte format is little-endian");

constexpr char kMagic[8] = {'C', 'S', 'T', 'S', 'D', 'F', '0', '2'};

// The settings as a fixed little-endian header (the grids carry no TsdfConfig).
struct Header {
    char magic[8];
    double voxel_size_m, truncation_voxels, behind_surface_voxels, ray_radius_voxels;
    double min_range_m, max_range_m;
    float max_weight, min_mesh_weight;
    std::uint32_t group_points_by_voxel;
    std::uint32_t weight_dropoff;
    std::uint64_t grid_bytes;
};

bool SameConfig(const TsdfConfig& a, const TsdfConfig& b) {
    return a.voxel_size_m == b.voxel_size_m && a.truncation_voxels == b.truncation_voxels &&
           a.behind_surface_voxels == b.behind_surface_voxels &&
           a.ray_radius_voxels == b.ray_radius_voxels && a.min_range_m == b.min_range_m &&
           a.max_range_m == b.max_range_m && a.max_weight == b.max_weight &&
           a.min_mesh_weight == b.min_mesh_weight &&
           a.group_points_by_voxel == b.group_points_by_voxel &&
           a.weight_dropoff == b.weight_dropoff;
}

// True when every active voxel of `a` is active in `b` with the same distance and weight.
bool Contains(const TsdfVolume::Impl& a, const TsdfVolume::Impl& b) {
    const auto b_w = b.weight->getConstAccessor();
    const auto b_s = b.sdf->getConstAccessor();
    const auto a_s = a.sdf->getConstAccessor();
    for (auto it = a.weight->cbeginValueOn(); it; ++it) {
        const openvdb::Coord ijk = it.getCoord();
        if (!b_w.isValueOn(ijk) || b_w.getValue(ijk) != *it ||
            b_s.getValue(ijk) != a_s.getValue(ijk)) {
            return false;
        }
    }
    return true;
}

}  // namespace

bool SameTsdfVoxels(const TsdfVolume::Impl& a, const TsdfVolume::Impl& b) {
    return SameConfig(a.config, b.config) &&
           a.weight->activeVoxelCount() == b.weight->activeVoxelCount() && Contains(a, b);
}

std::string SerializeTsdf(const TsdfVolume::Impl& impl) {
    std::ostringstream grids(std::ios::binary);
    openvdb::io::Stream stream(grids);
    stream.setCompression(openvdb::io::COMPRESS_BLOSC | openvdb::io::COMPRESS_ACTIVE_MASK);
    openvdb::GridCPtrVec vec{impl.sdf, impl.weight};
    stream.write(vec);
    const std::string grid_bytes = grids.str();

    const TsdfConfig& c = impl.config;
    Header h{};
    std::memcpy(h.magic, kMagic, sizeof kMagic);
    h.voxel_size_m = c.voxel_size_m;
    h.truncation_voxels = c.truncation_voxels;
    h.behind_surface_voxels = c.behind_surface_voxels;
    h.ray_radius_voxels = c.ray_radius_voxels;
    h.min_range_m = c.min_range_m;
    h.max_range_m = c.max_range_m;
    h.max_weight = c.max_weight;
    h.min_mesh_weight = c.min_mesh_weight;
    h.group_points_by_voxel = c.group_points_by_voxel ? 1 : 0;
    h.weight_dropoff = c.weight_dropoff ? 1 : 0;
    h.grid_bytes = grid_bytes.size();
    std::string out(sizeof h, '\0');
    std::memcpy(out.data(), &h, sizeof h);
    return out + grid_bytes;
}

std::unique_ptr<TsdfVolume::Impl> DeserializeTsdf(std::string_view bytes, std::string* error) {
    auto fail = [&](const std::string& what) {
        if (error != nullptr) *error = "TSDF bytes: " + what;
        return std::unique_ptr<TsdfVolume::Impl>();
    };
    Header h;
    if (bytes.size() < sizeof h) return fail("truncated header");
    std::memcpy(&h, bytes.data(), sizeof h);
    if (std::memcmp(h.magic, kMagic, sizeof kMagic) != 0) return fail("bad magic");
    if (h.grid_bytes != bytes.size() - sizeof h) return fail("grid length does not match");
    TsdfConfig c;
    c.voxel_size_m = h.voxel_size_m;
    c.truncation_voxels = h.truncation_voxels;
    c.behind_surface_voxels = h.behind_surface_voxels;
    c.ray_radius_voxels = h.ray_radius_voxels;
    c.min_range_m = h.min_range_m;
    c.max_range_m = h.max_range_m;
    c.max_weight = h.max_weight;
    c.min_mesh_weight = h.min_mesh_weight;
    c.group_points_by_voxel = h.group_points_by_voxel != 0;
    c.weight_dropoff = h.weight_dropoff != 0;
    try {
        c.Validate();
        auto impl = std::make_unique<TsdfVolume::Impl>(c);
        std::istringstream in(std::string(bytes.substr(sizeof h)), std::ios::binary);
        openvdb::io::Stream stream(in, /*delayLoad=*/false);
        const openvdb::GridPtrVecPtr grids = stream.getGrids();
        openvdb::FloatGrid::Ptr sdf, weight;
        for (const auto& g : *grids) {
            if (g->getName() == "sdf") sdf = openvdb::gridPtrCast<openvdb::FloatGrid>(g);
            if (g->getName() == "weight") weight = openvdb::gridPtrCast<openvdb::FloatGrid>(g);
        }
        if (!sdf || !weight) return fail("missing float grids 'sdf' and 'weight'");
        if (sdf->voxelSize()[0] != c.voxel_size_m || weight->voxelSize()[0] != c.voxel_size_m) {
            return fail("grid voxel size differs from the header's");
        }
        impl->sdf = sdf;
        impl->weight = weight;
        impl->MarkAllDirty();
        return impl;
    } catch (const std::exception& e) {
        return fail(e.what());
    }
}

}  // namespace certislam::slam
