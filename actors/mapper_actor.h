// TSDF mapper actor: integrates this robot's keyframes into submaps anchored to keyframes, moves
// them (no re-integration) when the solver's trajectory changes, sends its submaps to the peers
// as compressed bytes (a moved submap as its new anchor pose only) and fuses the peers' submaps
// into the same map, so the robots that keep the team's map can mesh it in the common frame.
// Bandwidth: a submap's bytes go out once it is closed (or the keyframes paused or ended), a
// submap that only moved goes out as its anchor pose, and only to peers that subscribed (the
// robots whose MapperConfig::team_map says they fuse their peers' submaps).
#pragma once

#include <Eigen/Geometry>
#include <atomic>
#include <chrono>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <vector>

#include "actors/node_actor.h"
#include "certislam/v1/rbcd.pb.h"
#include "slam/mapping/mesh.h"
#include "slam/mapping/submap.h"

namespace certislam::actors {

/// Which robots of the team fuse their peers' submaps (the others map only their own, and
/// nothing is sent to them: a publisher with no subscriber sends nothing).
enum class TeamMap {
    kAnchor,  ///< only the team's anchor (lowest robot id) keeps the team's map
    kAll,     ///< every robot keeps the team's map
    kNone,    ///< every robot keeps only its own map
};

/// Settings of the mapper.
struct MapperConfig {
    slam::TsdfMapConfig map;                        ///< submaps and their TSDF volumes
    std::chrono::milliseconds publish_period{500};  ///< changed submaps out this often, > 0
    bool share = true;                              ///< send own submaps to the peers that ask
    TeamMap team_map = TeamMap::kAnchor;            ///< which robots fuse their peers' submaps
    /// The active (still growing) submap's bytes go out only when it is closed, the keyframes
    /// ended, or no keyframe came for this long (>= 0): a growing submap is not re-sent whole
    /// on every publish tick.
    std::chrono::milliseconds active_submap_quiet{1000};
    /// zstd level of submap payloads on the wire, [0, 19] (0: uncompressed). The submap bytes
    /// hold raw voxels (masks and byte-planed floats), which zstd 3 about halves.
    int zstd_level = 3;
    /// Bits of a shared submap's distances (slam::SerializeSubmap): 32, lossless floats; 16 or 8,
    /// quantised (weights to one byte): each distance moves by at most 1/65534 (16) or 1/254 (8)
    /// of the submap's largest distance.
    int share_sdf_bits = 16;
    /// Threads that fuse and mesh the team map's slabs (FusedMesh), >= 1.
    int mesh_threads = 2;

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// What the mapper has done so far (a copy; thread-safe to take).
struct MapperStats {
    int integrated = 0;                   ///< own keyframes fused
    int own_submaps = 0;                  ///< own submaps
    int peer_submaps = 0;                 ///< submaps received from peers (distinct ids)
    int trajectory_updates = 0;           ///< solver trajectories applied
    int submaps_moved = 0;                ///< re-anchorings of own submaps (sum over updates)
    int peer_moves = 0;                   ///< peers' pose-only updates applied
    int submap_sends = 0;                 ///< own submaps sent with their bytes
    int pose_only_sends = 0;              ///< own submaps sent as their anchor pose only
    std::uint64_t submap_bytes_sent = 0;  ///< compressed submap payloads sent to peers
    slam::TsdfMapBudget budget;           ///< voxel memory, coarsenings and skipped scans
};

/// One robot's TSDF mapper.
class MapperActor final : public NodeActor {
  public:
    MapperActor(zmq::context_t& context, TeamWiring wiring, MapperConfig config);
    ~MapperActor() override { Stop(); }

    /// The counters now (thread-safe).
    MapperStats Stats() const;
    /// True when this robot fuses its peers' submaps (MapperConfig::team_map).
    bool FusesPeers() const;
    /// Every submap (own and peers') fused into one volume of voxel `voxel_m` in the common frame
    /// and meshed. Runs on the actor's thread while it runs (waits for it), directly otherwise.
    slam::TriangleMesh FusedMesh(double voxel_m);

  protected:
    void OnStart() override;
    void OnStop() override { CloseEndpoints(); }

  private:
    bool OnKeyframe(const transport::Message& m);
    bool OnTrajectory(const transport::Message& m);
    bool OnMapUpdate(const transport::Message& m);
    bool OnShutdown(const transport::Message& m);
    std::optional<Eigen::Isometry3d> Estimate(int index) const;
    void Publish();
    void UpdateStats();
    slam::TriangleMesh MakeMesh(double voxel_m) const;

    MapperConfig config_;
    slam::TsdfMap map_;
    transport::Endpoint* map_out_ = nullptr;
    std::map<int, Eigen::Isometry3d> odometry_;  ///< own keyframe -> T_odom_sensor
    std::map<int, Eigen::Isometry3d> solved_;    ///< own keyframe -> latest solver pose
    std::set<slam::SubmapId> dirty_;             ///< own submaps whose voxels changed
    std::set<slam::SubmapId> moved_;             ///< own submaps whose anchor pose changed
    std::set<slam::SubmapId> peers_;             ///< peers' submaps received
    std::optional<slam::SubmapId> active_;       ///< own submap keyframes go into now
    std::chrono::steady_clock::time_point last_keyframe_;  ///< last own keyframe fused
    bool keyframes_ended_ = false;                         ///< the ingest's end marker came
    std::size_t seen_subscribers_ = 0;                     ///< map subscribers at the last publish
    mutable std::mutex stats_mutex_;
    MapperStats stats_;
};

}  // namespace certislam::actors
