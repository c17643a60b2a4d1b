// TSDF submaps anchored to keyframe poses: re-anchored (not re-integrated) when the trajectory
// is corrected, fused across robots into one frame, and exchanged as compressed bytes.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "slam/core/keyframe.h"
#include "slam/core/pose_graph.h"
#include "slam/mapping/mesh.h"
#include "slam/mapping/tsdf.h"

namespace certislam::slam {

/// Names one submap: the robot that built it and its index among that robot's submaps.
struct SubmapId {
    int robot = 0;  ///< robot id
    int index = 0;  ///< from 0, in creation order

    friend bool operator==(const SubmapId&, const SubmapId&) = default;
    friend auto operator<=>(const SubmapId&, const SubmapId&) = default;
};

/// A TSDF volume in the frame of the keyframe that anchors it (Dubois et al. 2020). Scans are
/// integrated with their pose relative to the anchor, so the volume is rigid: a corrected
/// trajectory moves T_world_submap only.
struct Submap {
    SubmapId id;                                                       ///< who built it
    PoseId anchor;                                                     ///< anchoring keyframe
    Eigen::Isometry3d T_world_submap = Eigen::Isometry3d::Identity();  ///< anchor pose estimate
    std::vector<int> keyframes;  ///< keyframe indices (of id.robot) integrated, in order
    TsdfVolume volume;           ///< the distances, in the submap (anchor) frame
};

/// Settings of a TsdfMap. The defaults are the only defaults.
struct TsdfMapConfig {
    TsdfConfig tsdf;                  ///< settings of every submap's volume
    double submap_distance_m = 20.0;  ///< a keyframe farther than this from the active submap's
                                      ///< anchor starts a new submap, metres, in (0, 1000]
    int submap_max_keyframes = 0;     ///< a submap holding this many keyframes is closed, >= 0
                                      ///< (0: no limit)
    double memory_budget_mb = 64.0;   ///< voxel memory of all submaps at most, MiB (0: none); over
                                      ///< it, new submaps are coarser, then scans are skipped
    int max_coarsening = 3;           ///< voxels grow at most 2^this times over budget, in [0, 6]
    bool pack_closed_submaps = true;  ///< a closed own submap and a peer's submap keep only their
                                      ///< compressed bytes (TsdfVolume::Pack), decoded when
                                      ///< meshed or fused; the budget counts those bytes

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// What one TsdfMap::Insert did.
struct TsdfMapInsertResult {
    enum class Status {
        kIntegrated,   ///< the scan was fused into submap `submap`
        kNoValidRays,  ///< every point was out of range: nothing changed (no submap started)
        kOverBudget,   ///< the map is over its memory budget at the coarsest voxel: skipped
    };
    Status status = Status::kIntegrated;  ///< how the call ended
    bool started_submap = false;          ///< this keyframe anchors a new submap
    std::size_t submap = 0;               ///< index in submaps() of the submap it went into
    TsdfIntegrateResult integrate;        ///< the volume update
};

/// How a TsdfMap kept within its memory budget.
struct TsdfMapBudget {
    std::size_t memory_bytes = 0;  ///< voxel memory of every submap now (OpenVDB's memUsage of a
                                   ///< live volume, the bytes held by a packed one)
    int coarsenings = 0;           ///< times the voxel of new submaps was doubled
    double voxel_size_m = 0.0;     ///< voxel of the next own submap
    int skipped_scans = 0;         ///< keyframes not integrated: over budget at the coarsest voxel
};

/// A robot's map as submaps, plus submaps received from peers. Keyframe poses are given in
/// one world frame (the team's common frame once the solver aligned the robots).
class TsdfMap {
  public:
    /// An empty map of `robot`; `config` is validated (throws std::invalid_argument).
    explicit TsdfMap(int robot, const TsdfMapConfig& config = {});

    /// Fuses keyframe `keyframe` of this robot, taken at `T_world_sensor` (current estimate),
    /// into the active submap, first starting a new submap anchored at this keyframe when
    /// there is none, it is too far from the anchor, or the active one is full.
    TsdfMapInsertResult Insert(int keyframe, const Eigen::Isometry3d& T_world_sensor,
                               const PointCloud& cloud);

    /// Moves every submap whose anchor `T_world_anchor` knows to that pose; no voxel is
    /// touched, so the cost is one call per submap. Returns the number of submaps moved.
    std::size_t Reanchor(
        const std::function<std::optional<Eigen::Isometry3d>(const PoseId&)>& T_world_anchor);

    /// Adds a submap built elsewhere (a peer's, after DeserializeSubmap); it replaces a submap
    /// with the same id. Later Insert calls never write into it (packed if pack_closed_submaps).
    void AddSubmap(Submap submap);

    /// The union of all submaps' meshes in the world frame (each submap meshed in its own
    /// frame, incrementally, then mapped by T_world_submap; overlaps are not merged).
    TriangleMesh ExtractMesh();

    /// All submaps fused into one volume in the world frame with `config`: every observed
    /// voxel of every submap is mapped by T_world_submap to the nearest voxel of the result
    /// and averaged by weight. Overlapping submaps (and robots) then give one surface.
    TsdfVolume Fuse(const TsdfConfig& config) const;

    /// Fuse(config)'s mesh, built slab by slab (TsdfVolume::FuseAndMesh): the same mesh without
    /// the whole fused volume in memory; in `pieces` that `run` may give threads (FuseAndMesh).
    TriangleMesh FusedMesh(const TsdfConfig& config, int pieces = 1,
                           const TsdfVolume::RunPieces& run = {}) const;

    /// The submaps, own and received, in insertion order.
    const std::vector<Submap>& submaps() const { return submaps_; }

    /// The robot this map belongs to.
    int robot() const { return robot_; }

    /// Memory now and what keeping within the budget cost.
    TsdfMapBudget Budget() const;

  private:
    /// Over budget before an insert: doubles the voxel of new submaps (closing the active one)
    /// while it may; true when the scan must be skipped (still over at the coarsest voxel).
    bool OverBudget();
    /// Ends writes into the active submap (packing it if pack_closed_submaps).
    void CloseActive();

    int robot_;
    TsdfMapConfig config_;
    std::vector<std::size_t> memory_;  // per submap, its volume's memUsage when last changed
    TsdfMapBudget budget_;
    std::vector<Submap> submaps_;
    std::optional<std::size_t> active_;              // index of the submap Insert writes into
    std::vector<std::optional<TriangleMesh>> mesh_;  // per submap, in its frame; nullopt: stale
};

/// The bytes of `submap` (what a robot sends a peer): ids, anchor pose, keyframe list
/// and the volume's voxels (TsdfVolume::Serialize: lossless with sdf_bits 32, else quantised).
std::string SerializeSubmap(const Submap& submap, int sdf_bits = 32);

/// Parses SerializeSubmap's bytes. Untrusted input: returns nullopt and sets `*error` naming
/// what was wrong. With `packed`, the volume keeps the received bytes (TsdfVolume::Pack).
std::optional<Submap> DeserializeSubmap(std::string_view bytes, std::string* error,
                                        bool packed = false);

}  // namespace certislam::slam
