// The TSDF mapper actor over real inproc sockets: two robots' mappers, the test playing each
// robot's ingest (keyframes) and solver (trajectory updates on the bundle stream). Robot 1's
// submap (a wall only robot 1 saw) reaches robot 0 as compressed bytes and is fused into robot
// 0's map; a trajectory update that moves robot 1's keyframe moves that wall in robot 0's mesh
// (a pose-only update, no re-integration). Bandwidth: by default only the anchor (robot 0)
// receives submaps, and a growing submap's bytes go out once, not on every publish tick.
#include <gtest/gtest.h>

#include <zstd.h>

#include <thread>

#include "actors/convert.h"
#include "actors/mapper_actor.h"
#include "certislam/v1/map.pb.h"

namespace certislam::actors {
namespace {

constexpr double kWallX_m = 8.0;          // robot 1's wall: the plane x = 8 in its sensor frame
constexpr double kWallY_m = 8.0;          // robot 0's wall: the plane y = 8
constexpr double kShiftZ_m = 3.0;         // the trajectory update lifts robot 1 by this
constexpr double kMeshTolerance_m = 0.3;  // vertex placement tolerance (voxel 0.2 m)
constexpr auto kWait = std::chrono::seconds(20);
constexpr int kScans = 3;

slam::PointCloudPtr Wall(bool along_x) {
    auto cloud = std::make_shared<slam::PointCloud>();
    for (double u = -4.0; u <= 4.0; u += 0.05) {
        for (double z = -1.5; z <= 1.5; z += 0.05) {
            cloud->push_back(along_x ? Eigen::Vector3f(kWallX_m, u, z)
                                     : Eigen::Vector3f(u, kWallY_m, z));
        }
    }
    return cloud;
}

template <typename Pred>
bool WaitFor(Pred pred) {
    const auto deadline = std::chrono::steady_clock::now() + kWait;
    while (!pred()) {
        if (std::chrono::steady_clock::now() > deadline) return false;
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return true;
}

/// Mean position of the mesh vertices with x beyond `x_min` (robot 1's wall), and their count.
std::pair<Eigen::Vector3d, int> WallVertices(const slam::TriangleMesh& mesh, double x_min) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    int n = 0;
    for (const auto& v : mesh.vertices) {
        if (v.x() > x_min) {
            sum += v.cast<double>();
            ++n;
        }
    }
    return {n > 0 ? Eigen::Vector3d(sum / n) : sum, n};
}

struct Robot {
    std::unique_ptr<transport::Endpoint> keyframes;
    std::unique_ptr<transport::Endpoint> bundle;
    std::unique_ptr<MapperActor> mapper;
};

/// Two robots' mappers over inproc, with the endpoints of their ingest and solver.
std::vector<Robot> StartTeam(zmq::context_t& context, const MapperConfig& config) {
    const std::vector<int> ids{0, 1};
    std::vector<Robot> robots(2);
    for (int r : ids) {
        const TeamWiring w = InprocWiring(r, ids);
        robots[r].keyframes =
            std::make_unique<transport::Endpoint>(context, ServerConfig(w, Edge::kKeyframes));
        robots[r].bundle =
            std::make_unique<transport::Endpoint>(context, ServerConfig(w, Edge::kBundle));
        robots[r].mapper = std::make_unique<MapperActor>(context, w, config);
    }
    for (auto& robot : robots) robot.mapper->Start();
    return robots;
}

slam::Keyframe WallKeyframe(int robot, int index) {
    slam::Keyframe kf;
    kf.robot = robot;
    kf.index = index;
    kf.T_odom_sensor.translation() = Eigen::Vector3d(0.0, 0.0, 0.1 * index);
    kf.cloud = Wall(robot == 1);
    return kf;
}

TEST(MapperActor, PeerSubmapIsFusedAndAMovedPoseMovesTheMesh) {
    zmq::context_t context;
    const std::vector<int> ids{0, 1};
    MapperConfig config;
    config.publish_period = std::chrono::milliseconds(100);
    config.team_map = TeamMap::kAll;
    std::vector<Robot> robots = StartTeam(context, config);
    for (int r : ids) {
        ASSERT_TRUE(robots[r].keyframes->WaitForSubscribers(1, std::chrono::seconds(5)));
        ASSERT_TRUE(robots[r].bundle->WaitForSubscribers(1, std::chrono::seconds(5)));
        for (int i = 0; i < kScans; ++i) {  // a few scans from nearby poses
            ASSERT_EQ(robots[r].keyframes->Send(EncodeKeyframe(WallKeyframe(r, i), i + 1)),
                      transport::SendStatus::kSent);
        }
    }
    MapperActor& m0 = *robots[0].mapper;
    ASSERT_TRUE(WaitFor([&] { return m0.Stats().peer_submaps == 1; }))
        << "robot 1's submap never reached robot 0";
    ASSERT_TRUE(WaitFor([&] { return m0.Stats().integrated == kScans; }));
    ASSERT_TRUE(WaitFor([&] { return robots[1].mapper->Stats().integrated == kScans; }));
    std::this_thread::sleep_for(config.publish_period * 3);  // the last scans' submap bytes
    EXPECT_EQ(m0.Stats().own_submaps, 1);
    EXPECT_GT(robots[1].mapper->Stats().submap_bytes_sent, 0u);

    const auto [own1, n_own1] = WallVertices(robots[1].mapper->FusedMesh(0.2), kWallX_m / 2);
    const auto [before, n_before] = WallVertices(m0.FusedMesh(0.2), kWallX_m / 2);
    EXPECT_EQ(n_before, n_own1);  // robot 0 meshes robot 1's wall as robot 1 does
    ASSERT_GT(n_before, 50) << "robot 1's wall is not in robot 0's fused mesh";
    EXPECT_NEAR(before.x(), kWallX_m, kMeshTolerance_m);

    Eigen::Isometry3d lifted = Eigen::Isometry3d::Identity();
    lifted.translation().z() = kShiftZ_m;
    auto update = TrajectoryToProto(1, {lifted}, true, 7);
    *update.mutable_header() = MakeHeader(1, 1, 0);
    const int moves = m0.Stats().peer_moves;
    ASSERT_EQ(robots[1].bundle->Send(transport::Pack(update)), transport::SendStatus::kSent);
    ASSERT_TRUE(WaitFor([&] { return m0.Stats().peer_moves > moves; }));
    EXPECT_EQ(robots[1].mapper->Stats().submaps_moved, 1);
    EXPECT_EQ(m0.Stats().peer_submaps, 1);  // moved, not re-sent
    const auto [after, n_after] = WallVertices(m0.FusedMesh(0.2), kWallX_m / 2);
    ASSERT_GT(n_after, 50);
    EXPECT_NEAR(after.z() - before.z(), kShiftZ_m, kMeshTolerance_m);
    EXPECT_NEAR(after.x(), before.x(), kMeshTolerance_m);

    for (auto& robot : robots) robot.mapper->Stop();
    EXPECT_EQ(m0.Counters().dropped_malformed, 0u);
    EXPECT_EQ(robots[1].mapper->Counters().dropped_malformed, 0u);
}

// Keyframes a few publish periods apart all go into one growing submap: its bytes go out once
// (after the keyframes paused), only to robot 0 (the anchor, TeamMap::kAnchor), and robot 0's
// submap goes nowhere (robot 1 does not subscribe to it).
TEST(MapperActor, OnlyTheAnchorReceivesSubmapsAndAGrowingSubmapIsSentOnce) {
    zmq::context_t context;
    MapperConfig config;  // team_map: kAnchor by default
    config.publish_period = std::chrono::milliseconds(100);
    config.active_submap_quiet = std::chrono::milliseconds(800);
    ASSERT_EQ(config.team_map, TeamMap::kAnchor);
    std::vector<Robot> robots = StartTeam(context, config);
    MapperActor &m0 = *robots[0].mapper, &m1 = *robots[1].mapper;
    EXPECT_TRUE(m0.FusesPeers());
    EXPECT_FALSE(m1.FusesPeers());
    for (int r : {0, 1}) {
        ASSERT_TRUE(robots[r].keyframes->WaitForSubscribers(1, std::chrono::seconds(5)));
    }
    for (int i = 0; i < kScans; ++i) {  // three publish ticks between keyframes
        for (int r : {0, 1}) {
            ASSERT_EQ(robots[r].keyframes->Send(EncodeKeyframe(WallKeyframe(r, i), i + 1)),
                      transport::SendStatus::kSent);
        }
        std::this_thread::sleep_for(config.publish_period * 3);
    }
    ASSERT_TRUE(WaitFor([&] { return m0.Stats().peer_submaps == 1; }));
    ASSERT_TRUE(WaitFor([&] { return m1.Stats().integrated == kScans; }));
    std::this_thread::sleep_for(config.active_submap_quiet + config.publish_period * 3);
    EXPECT_EQ(m1.Stats().own_submaps, 1);
    EXPECT_EQ(m1.Stats().submap_sends, 1);  // not once per tick while it grew
    EXPECT_GT(m1.Stats().submap_bytes_sent, 0u);
    EXPECT_EQ(m0.Stats().submap_sends, 0);  // nobody subscribed to robot 0's map
    EXPECT_EQ(m0.Stats().submap_bytes_sent, 0u);
    EXPECT_EQ(m1.Stats().peer_submaps, 0);
    // Robot 0 holds robot 1's wall with all three scans in it, as robot 1 meshes it.
    const auto [own1, n_own1] = WallVertices(m1.FusedMesh(0.2), kWallX_m / 2);
    const auto [at0, n_at0] = WallVertices(m0.FusedMesh(0.2), kWallX_m / 2);
    ASSERT_GT(n_own1, 50);
    EXPECT_EQ(n_at0, n_own1);
    for (auto& robot : robots) robot.mapper->Stop();
}

TEST(MapperConfig, RejectsANegativeActiveSubmapQuiet) {
    MapperConfig config;
    config.active_submap_quiet = std::chrono::milliseconds(-1);
    EXPECT_THROW(config.Validate(), std::invalid_argument);
}

TEST(MapperConfig, RejectsNoMeshThreadNamingTheField) {
    MapperConfig config;
    config.mesh_threads = 0;
    try {
        config.Validate();
        FAIL() << "0 mesh threads accepted";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("mesh_threads = 0"), std::string::npos);
    }
    config.mesh_threads = 1;
    EXPECT_NO_THROW(config.Validate());
}

TEST(MapperConfig, RejectsDistanceBitsOtherThan8_16Or32) {
    MapperConfig config;
    config.share_sdf_bits = 12;
    try {
        config.Validate();
        FAIL() << "12 bits accepted";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("share_sdf_bits = 12"), std::string::npos);
    }
    for (const int bits : {8, 16, 32}) {
        config.share_sdf_bits = bits;
        EXPECT_NO_THROW(config.Validate());
    }
}

/// Robot 1's wall as one serialized submap, zstd-compressed, in a MapUpdate that says so.
transport::Message CompressedWallUpdate(std::uint64_t declared_size) {
    slam::TsdfMap map(1);
    for (int i = 0; i < kScans; ++i) {  // the scans robot 1's mapper fuses in the test above
        const slam::Keyframe kf = WallKeyframe(1, i);
        map.Insert(i, kf.T_odom_sensor, *kf.cloud);
    }
    const std::string raw = slam::SerializeSubmap(map.submaps().front());
    std::string z(ZSTD_compressBound(raw.size()), '\0');
    z.resize(ZSTD_compress(z.data(), z.size(), raw.data(), raw.size(), 3));
    v1::MapUpdate update;
    *update.mutable_header() = MakeHeader(1, 1, 0);
    update.set_submap_id(0);
    *update.mutable_anchor_pose_id() = ToProto(slam::PoseId{1, 0});
    *update.mutable_t_world_anchor() = ToProto(Eigen::Isometry3d::Identity());
    update.set_kind(v1::MAP_PAYLOAD_KIND_TSDF_BLOCKS);
    update.set_compression(v1::MAP_COMPRESSION_ZSTD);
    update.set_frame_index(0);
    update.set_byte_length(z.size());
    update.set_uncompressed_byte_length(declared_size == 0 ? raw.size() : declared_size);
    return transport::Pack(update, {transport::SharedBuffer::Copy(z.data(), z.size())});
}

// Untrusted map bytes: a zstd frame whose declared size lies is dropped and counted; the honest
// frame of the same submap is decompressed and fused.
TEST(MapperActor, CompressedSubmapWithALyingSizeIsDroppedAndTheHonestOneFused) {
    zmq::context_t context;
    const std::vector<int> ids{0, 1};
    MapperActor m0(context, InprocWiring(0, ids), MapperConfig{});
    transport::Endpoint peer(context, ServerConfig(InprocWiring(1, ids), Edge::kMap));
    m0.Start();
    ASSERT_TRUE(peer.WaitForSubscribers(1, std::chrono::seconds(5)));
    ASSERT_EQ(peer.Send(CompressedWallUpdate(12345)), transport::SendStatus::kSent);
    ASSERT_TRUE(WaitFor([&] { return m0.Counters().dropped_malformed == 1; }));
    EXPECT_EQ(m0.Stats().peer_submaps, 0);
    ASSERT_EQ(peer.Send(CompressedWallUpdate(0)), transport::SendStatus::kSent);
    ASSERT_TRUE(WaitFor([&] { return m0.Stats().peer_submaps == 1; }));
    EXPECT_GT(WallVertices(m0.FusedMesh(0.2), kWallX_m / 2).second, 50);
    EXPECT_EQ(m0.Counters().dropped_malformed, 1u);
    m0.Stop();
}

}  // namespace
}  // namespace certislam::actors
