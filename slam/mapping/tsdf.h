// A sparse truncated signed distance field for LiDAR scans on OpenVDB (VDBFusion-style).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "slam/core/keyframe.h"
#include "slam/mapping/mesh.h"

namespace certislam::slam {

/// Settings of one TSDF volume. The defaults are the only defaults.
struct TsdfConfig {
    double voxel_size_m = 0.2;       ///< voxel edge, metres, in [0.01, 5]
    double truncation_voxels = 3.0;  ///< extent of the band updated in front of each hit, voxels,
                                     ///< in [1, 20]; the truncation distance is this x voxel
    double behind_surface_voxels = 2.0;  ///< extent of the band behind each hit, voxels, in
                                         ///< [0.5, truncation_voxels]: behind a hit the space is
                                         ///< presumed occupied, not observed; a deep band lets
                                         ///< rays grazing one face of a corner carve negative
                                         ///< distance into the free space past the corner
    double ray_radius_voxels = 0.5;     ///< a ray updates only voxels whose centre lies within this
                                        ///< distance of it, voxels, in [0.1, 0.87]: the projective
                                        ///< distance of an off-ray centre errs by up to its offset
                                        ///< at grazing incidence, so 0.5 bounds it by half a voxel
    double min_range_m = 0.5;           ///< hits nearer than this to the sensor are ignored, >= 0
    double max_range_m = 100.0;         ///< hits farther than this are ignored, > min_range_m
    float max_weight = 1.0e4f;          ///< the running-average weight saturates here, > 0
    bool group_points_by_voxel = true;  ///< merge the points that end in one voxel into a single
                                        ///< ray (mean end point, weight 1) before casting
    bool weight_dropoff = true;  ///< behind a hit the weight falls linearly from 1 at the hit to 0
                                 ///< at -behind_surface (Curless & Levoy 1996's ramp)
    float min_mesh_weight = 0.5f;  ///< a cube is meshed only if all 8 corners weigh more, >= 0

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
    /// The truncation distance in metres.
    double truncation_m() const { return truncation_voxels * voxel_size_m; }
};

/// What one Integrate call did.
struct TsdfIntegrateResult {
    enum class Status {
        kOk,           ///< at least one ray updated the volume
        kNoValidRays,  ///< every point was out of range (or the cloud was empty)
    };
    Status status = Status::kOk;    ///< how the call ended
    std::size_t points_used = 0;    ///< points within [min_range_m, max_range_m]
    std::size_t rays_cast = 0;      ///< rays traversed (fewer than points when grouped)
    std::size_t voxel_updates = 0;  ///< voxel updates made (one ray updates ~2x truncation)
};

/// Memory and size of a volume.
struct TsdfStats {
    std::size_t active_voxels = 0;     ///< voxels holding an observation
    std::size_t allocated_voxels = 0;  ///< voxels in allocated 8^3 leaf blocks (>= active)
    std::size_t leaf_blocks = 0;       ///< allocated 8^3 leaf blocks
    std::size_t memory_bytes = 0;      ///< OpenVDB's memUsage() of the distance + weight grids,
                                       ///< or the bytes held when the volume is packed
};

/// One voxel's stored state.
struct TsdfVoxel {
    float sdf_m = 0.0f;   ///< truncated signed distance, metres (positive in front of surfaces)
    float weight = 0.0f;  ///< accumulated weight (0: never observed)
};

/// A sparse TSDF: a distance grid and a weight grid (OpenVDB FloatGrids) updated only within
/// the truncation band around each hit, so memory is allocated only near surfaces (no
/// free-space carving along whole rays). The volume has its own frame; callers give scans
/// with the pose of the sensor in that frame. Voxel (i, j, k) is centred at voxel_size * (i,j,k).
class TsdfVolume {
  public:
    /// An empty volume; `config` is validated (throws std::invalid_argument).
    explicit TsdfVolume(const TsdfConfig& config = {});
    ~TsdfVolume();
    TsdfVolume(TsdfVolume&&) noexcept;
    TsdfVolume& operator=(TsdfVolume&&) noexcept;
    TsdfVolume(const TsdfVolume&) = delete;
    TsdfVolume& operator=(const TsdfVolume&) = delete;

    /// A deep copy (grids and mesh cache).
    TsdfVolume Clone() const;

    /// Fuses one scan: `points` in the sensor frame, `T_volume_sensor` the sensor pose. Each
    /// ray updates the voxels near it from truncation_m before its hit to behind_surface after
    /// it with the projective (along-ray) distance, as a weighted running average
    /// (KinectFusion / VDBFusion update).
    TsdfIntegrateResult Integrate(const PointCloud& points,
                                  const Eigen::Isometry3d& T_volume_sensor);

    /// Fuses every observed voxel of `other` into this volume: its centre is mapped by
    /// `T_this_other` to the nearest voxel here and averaged in by weight (distances in metres
    /// are unchanged by rigid motion). Used to merge submaps and robots into one frame.
    void FuseVoxels(const TsdfVolume& other, const Eigen::Isometry3d& T_this_other);

    /// The voxel nearest to `p_volume`, or nullopt when it was never observed.
    std::optional<TsdfVoxel> Query(const Eigen::Vector3d& p_volume) const;

    /// One volume of a fusion and its pose in the fused frame.
    struct FusePart {
        const TsdfVolume* volume = nullptr;                              ///< not owned
        Eigen::Isometry3d T_fused_part = Eigen::Isometry3d::Identity();  ///< its pose
    };

    /// Calls piece(0), ..., piece(n - 1), in any order, on any threads, and returns when all
    /// have returned. The pieces share no mutable state. Empty: in order, on the caller's thread.
    using RunPieces = std::function<void(int n, const std::function<void(int)>& piece)>;

    /// The mesh of a volume with `config` into which every part was fused in order (FuseVoxels,
    /// then ExtractMesh), built in slabs of `slab_blocks` 8^3 blocks along x: the same mesh, with
    /// one slab of the fused volume (and the packed parts that overlap it, decoded) per piece in
    /// memory at a time. The slabs are split into at most `pieces` runs of about equal fusion work,
    /// which `run` meshes (the caller may give it threads; this library starts none), then welded
    /// in order. A packed part that spans two runs is decoded by each.
    static TriangleMesh FuseAndMesh(const std::vector<FusePart>& parts, const TsdfConfig& config,
                                    int slab_blocks = 8, int pieces = 1, const RunPieces& run = {});

    /// The zero level set as a mesh in the volume frame (marching cubes over cubes whose 8
    /// corners weigh more than min_mesh_weight). Incremental: only the 8^3 blocks touched since
    /// the last call (and their neighbours) are re-meshed; the rest come from a cache. A packed
    /// volume is meshed whole from a temporary copy (the same mesh).
    TriangleMesh ExtractMesh();

    /// Number of blocks re-meshed by the last ExtractMesh call.
    std::size_t last_remeshed_blocks() const;

    /// Sizes and memory.
    TsdfStats Stats() const;

    /// The settings the volume was built with.
    const TsdfConfig& config() const;

    /// True when both volumes hold the same voxels with bit-identical values and settings.
    bool SameVoxels(const TsdfVolume& other) const;

    /// Bytes of the settings and the active voxels (tsdf_serialize.h's checked format,
    /// uncompressed: Pack and the mapper's wire add zstd). sdf_bits 32: lossless; 16 or 8:
    /// quantised (each value moves by at most half its step), as a mapper's peers get them.
    std::string Serialize(int sdf_bits = 32) const;

    /// Parses Serialize's bytes. Untrusted input: returns nullopt and sets `*error` on failure.
    static std::optional<TsdfVolume> Deserialize(std::string_view bytes, std::string* error);

    /// Keeps only Serialize's lossless bytes (and Stats' sizes): the grids and the mesh cache are
    /// freed. Reading a packed volume (Query, Stats, ExtractMesh, SameVoxels, Serialize, Clone,
    /// FuseVoxels as the source) decodes a temporary copy and leaves it packed; writing into it
    /// (Integrate, FuseVoxels as the target) unpacks it for good first. Idempotent.
    void Pack();

    /// True from Pack (or DeserializePacked) until the next write.
    bool packed() const;

    /// Deserialize, then kept packed: the bytes are checked by a full decode, then only they stay.
    static std::optional<TsdfVolume> DeserializePacked(std::string_view bytes, std::string* error);

    /// The OpenVDB state, opaque here (defined in tsdf_impl.h, private to tsdf*.cpp).
    struct Impl;

  private:
    explicit TsdfVolume(std::unique_ptr<Impl> impl);
    /// The live state to write into (unpacks a packed volume).
    Impl& Writable();
    std::unique_ptr<Impl> impl_;
};

}  // namespace certislam::slam
