// TSDF mapper: keyframes in -> submaps; solver trajectories in -> re-anchoring; own submaps out
// to the peers that fuse them (bytes once a submap is closed or the keyframes paused, anchor pose
// only when it just moved); peers' submaps in -> the same map.
#include "actors/mapper_actor.h"

#include <zstd.h>

#include <functional>
#include <future>
#include <memory>
#include <stdexcept>
#include <string>

#include "actors/convert.h"
#include "actors/streams.h"
#include "certislam/v1/control.pb.h"
#include "certislam/v1/map.pb.h"
#include "slam/core/check.h"

namespace certislam::actors {
namespace {

constexpr double kMovedTranslation_m = 1e-4;  // anchor changes below these are not sent
constexpr double kMovedRotation_rad = 1e-5;
constexpr auto kMeshWait = std::chrono::seconds(120);

/// The zstd frame of `payload` at `level`.
std::string Compress(const std::string& payload, int level) {
    std::string out(ZSTD_compressBound(payload.size()), '\0');
    const std::size_t n =
        ZSTD_compress(out.data(), out.size(), payload.data(), payload.size(), level);
    CERTISLAM_CHECK(!ZSTD_isError(n));
    out.resize(n);
    return out;
}

bool Moved(const Eigen::Isometry3d& before, const Eigen::Isometry3d& after) {
    const Eigen::Isometry3d d = before.inverse() * after;
    return d.translation().norm() > kMovedTranslation_m ||
           Eigen::AngleAxisd(d.linear()).angle() > kMovedRotation_rad;
}

}  // namespace

void MapperConfig::Validate() const {
    map.Validate();
    if (publish_period.count() <= 0) {
        throw std::invalid_argument("MapperConfig.publish_period = " +
                                    std::to_string(publish_period.count()) + " ms: must be > 0");
    }
    if (zstd_level < 0 || zstd_level > 19) {
        throw std::invalid_argument("MapperConfig.zstd_level = " + std::to_string(zstd_level) +
                                    ": must be in [0, 19]");
    }
    if (share_sdf_bits != 8 && share_sdf_bits != 16 && share_sdf_bits != 32) {
        throw std::invalid_argument("MapperConfig.share_sdf_bits = " +
                                    std::to_string(share_sdf_bits) + ": must be 8, 16 or 32");
    }
    if (mesh_threads < 1) {
        throw std::invalid_argument("MapperConfig.mesh_threads = " + std::to_string(mesh_threads) +
                                    ": must be >= 1");
    }
    if (active_submap_quiet.count() < 0) {
        throw std::invalid_argument(
            "MapperConfig.active_submap_quiet = " + std::to_string(active_submap_quiet.count()) +
            " ms: must be >= 0");
    }
}

MapperActor::MapperActor(zmq::context_t& context, TeamWiring wiring, MapperConfig config)
    : NodeActor("mapper", context, std::move(wiring)),
      config_(config),
      map_((config.Validate(), RobotId()), config.map) {}

void MapperActor::OnStart() {
    map_out_ = &OpenServer(Edge::kMap);
    OpenClient(Edge::kKeyframes, RobotId());
    OpenClient(Edge::kBundle, RobotId());  // the solver's trajectory closes each bundle
    for (int r : Wiring().robots) {
        if (r != RobotId() && FusesPeers()) OpenClient(Edge::kMap, r);
    }
    On(v1::Keyframe::descriptor()->full_name(),
       [this](const transport::Message& m) { return OnKeyframe(m); });
    On(v1::TrajectoryUpdate::descriptor()->full_name(),
       [this](const transport::Message& m) { return OnTrajectory(m); });
    On(v1::MapUpdate::descriptor()->full_name(),
       [this](const transport::Message& m) { return OnMapUpdate(m); });
    On(v1::Shutdown::descriptor()->full_name(),
       [this](const transport::Message& m) { return OnShutdown(m); });
    Every(config_.publish_period, [this] { Publish(); });
}

MapperStats MapperActor::Stats() const {
    std::lock_guard lock(stats_mutex_);
    return stats_;
}

bool MapperActor::FusesPeers() const {
    switch (config_.team_map) {
        case TeamMap::kAll:
            return true;
        case TeamMap::kNone:
            return false;
        case TeamMap::kAnchor:
            return RobotId() == Wiring().robots.front();
    }
    return false;
}

std::optional<Eigen::Isometry3d> MapperActor::Estimate(int index) const {
    const auto odom = odometry_.find(index);
    if (odom == odometry_.end()) return std::nullopt;
    if (const auto it = solved_.find(index); it != solved_.end()) return it->second;
    // Not solved yet: the latest solved keyframe before it, then odometry from there.
    auto before = solved_.lower_bound(index);
    if (before == solved_.begin()) return odom->second;  // nothing solved: the odometry frame
    --before;
    return before->second * odometry_.at(before->first).inverse() * odom->second;
}

bool MapperActor::OnKeyframe(const transport::Message& m) {
    const auto keyframe = DecodeKeyframe(m);
    if (!keyframe || keyframe->robot != RobotId()) return false;
    if (odometry_.count(keyframe->index)) return true;  // a republished keyframe
    odometry_[keyframe->index] = keyframe->T_odom_sensor;
    const auto result = map_.Insert(keyframe->index, *Estimate(keyframe->index), *keyframe->cloud);
    if (result.status == slam::TsdfMapInsertResult::Status::kIntegrated) {
        active_ = map_.submaps()[result.submap].id;
        dirty_.insert(*active_);
    }
    last_keyframe_ = std::chrono::steady_clock::now();
    UpdateStats();
    std::lock_guard lock(stats_mutex_);
    if (result.status == slam::TsdfMapInsertResult::Status::kIntegrated) ++stats_.integrated;
    return true;
}

bool MapperActor::OnTrajectory(const transport::Message& m) {
    const auto proto = transport::Unpack<v1::TrajectoryUpdate>(m);
    const auto poses = proto ? TrajectoryFromProto(*proto) : std::nullopt;
    if (!poses || int(proto->header().robot_id()) != RobotId()) return false;
    for (const auto& [id, T] : *poses) {
        if (id.robot == RobotId()) solved_[id.index] = T;
    }
    std::map<slam::SubmapId, Eigen::Isometry3d> before;
    for (const auto& s : map_.submaps()) before[s.id] = s.T_world_submap;
    map_.Reanchor([&](const slam::PoseId& id) -> std::optional<Eigen::Isometry3d> {
        if (id.robot != RobotId()) return std::nullopt;
        const auto it = solved_.find(id.index);
        return it == solved_.end() ? std::nullopt : std::optional(it->second);
    });
    int moved = 0;
    for (const auto& s : map_.submaps()) {
        if (s.id.robot == RobotId() && Moved(before.at(s.id), s.T_world_submap)) {
            moved_.insert(s.id);
            ++moved;
        }
    }
    std::lock_guard lock(stats_mutex_);
    ++stats_.trajectory_updates;
    stats_.submaps_moved += moved;
    return true;
}

bool MapperActor::OnShutdown(const transport::Message& m) {
    const auto end = transport::Unpack<v1::Shutdown>(m);
    if (!end) return false;
    if (end->reason() == kEndOfKeyframes && int(end->header().robot_id()) == RobotId()) {
        keyframes_ended_ = true;  // the active submap is complete: it may go out now
    }
    return true;
}

bool MapperActor::OnMapUpdate(const transport::Message& m) {
    const auto body = DecodeMapUpdate(m);
    if (!body || body->sender == RobotId()) return false;
    const slam::SubmapId id{body->sender, body->submap};
    if (!body->bytes) {                      // moved only
        if (!peers_.count(id)) return true;  // its bytes have not arrived yet: they will
        map_.Reanchor([&](const slam::PoseId& p) -> std::optional<Eigen::Isometry3d> {
            return p == body->anchor ? std::optional(body->T_world_anchor) : std::nullopt;
        });
        std::lock_guard lock(stats_mutex_);
        ++stats_.peer_moves;
        return true;
    }
    std::string error;
    auto submap = slam::DeserializeSubmap(*body->bytes, &error, config_.map.pack_closed_submaps);
    if (!submap || !(submap->id == id) || !(submap->anchor == body->anchor)) return false;
    submap->T_world_submap = body->T_world_anchor;
    map_.AddSubmap(std::move(*submap));
    peers_.insert(id);
    UpdateStats();
    return true;
}

void MapperActor::Publish() {
    if (!config_.share) {
        dirty_.clear();
        moved_.clear();
        return;
    }
    // A peer that subscribed since the last tick (late, or restarted) gets every own submap.
    const std::size_t subscribers = map_out_->subscribers();
    if (subscribers > seen_subscribers_) {
        for (const auto& s : map_.submaps()) {
            if (s.id.robot == RobotId()) dirty_.insert(s.id);
        }
        seen_subscribers_ = subscribers;
    }
    if (subscribers == 0) return;  // nobody listens (yet): the changes wait
    // The growing submap would be re-sent whole on every tick: it waits until it is closed (a
    // later submap became active) or the keyframes ended or paused.
    const bool active_ready =
        keyframes_ended_ ||
        std::chrono::steady_clock::now() - last_keyframe_ >= config_.active_submap_quiet;
    std::uint64_t bytes = 0;
    int sends = 0, pose_only = 0;
    for (const auto& s : map_.submaps()) {
        const bool dirty = dirty_.count(s.id) > 0 && (s.id != active_ || active_ready);
        const bool moved = moved_.count(s.id) > 0;
        if (s.id.robot != RobotId() || (!dirty && !moved)) continue;
        v1::MapUpdate update;
        *update.mutable_header() = MakeHeader(RobotId(), NextSequence(), 0);
        update.set_submap_id(static_cast<std::uint64_t>(s.id.index));
        *update.mutable_anchor_pose_id() = ToProto(s.anchor);
        *update.mutable_t_world_anchor() = ToProto(s.T_world_submap);
        update.set_voxel_size_m(static_cast<float>(s.volume.config().voxel_size_m));
        std::vector<transport::SharedBuffer> frames;
        if (dirty) {  // the submap bytes hold voxels (tsdf_serialize.h): zstd packs them
            const std::string raw = slam::SerializeSubmap(s, config_.share_sdf_bits);
            const std::string payload =
                config_.zstd_level > 0 ? Compress(raw, config_.zstd_level) : raw;
            update.set_kind(v1::MAP_PAYLOAD_KIND_TSDF_BLOCKS);
            update.set_compression(config_.zstd_level > 0 ? v1::MAP_COMPRESSION_ZSTD
                                                          : v1::MAP_COMPRESSION_NONE);
            update.set_frame_index(0);
            update.set_byte_length(payload.size());
            update.set_uncompressed_byte_length(raw.size());
            frames.push_back(transport::SharedBuffer::Copy(payload.data(), payload.size()));
            bytes += payload.size();
            dirty_.erase(s.id);
        }
        ++(dirty ? sends : pose_only);
        Send(*map_out_, transport::Pack(update, std::move(frames)), true);
    }
    moved_.clear();
    std::lock_guard lock(stats_mutex_);
    stats_.submap_bytes_sent += bytes;
    stats_.submap_sends += sends;
    stats_.pose_only_sends += pose_only;
}

void MapperActor::UpdateStats() {
    int own = 0;
    for (const auto& s : map_.submaps()) own += s.id.robot == RobotId() ? 1 : 0;
    std::lock_guard lock(stats_mutex_);
    stats_.own_submaps = own;
    stats_.peer_submaps = static_cast<int>(peers_.size());
    stats_.budget = map_.Budget();
}

slam::TriangleMesh MapperActor::MakeMesh(double voxel_m) const {
    slam::TsdfConfig config = config_.map.tsdf;
    config.voxel_size_m = voxel_m;
    // Slab by slab (not the whole fused volume at once), in one piece per thread.
    const auto run = [](int n, const std::function<void(int)>& piece) {
        std::vector<std::future<void>> others;
        for (int k = 1; k < n; ++k) others.push_back(std::async(std::launch::async, piece, k));
        piece(0);
        for (auto& f : others) f.get();
    };
    return map_.FusedMesh(config, config_.mesh_threads, run);
}

slam::TriangleMesh MapperActor::FusedMesh(double voxel_m) {
    if (!Running()) return MakeMesh(voxel_m);
    auto done = std::make_shared<std::promise<slam::TriangleMesh>>();
    auto result = done->get_future();
    Post([this, done, voxel_m] { done->set_value(MakeMesh(voxel_m)); });
    if (result.wait_for(kMeshWait) != std::future_status::ready) return {};
    return result.get();
}

}  // namespace certislam::actors
