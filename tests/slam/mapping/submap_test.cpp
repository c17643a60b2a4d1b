// Tests of TSDF submaps: creation policy, rigid re-anchoring, equivalence of trajectories up to
// per-submap corrections, fusion across robots, and the bytes a robot sends a peer.
#include "slam/mapping/submap.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <functional>
#include <future>
#include <random>
#include <stdexcept>

#include "tests/slam/mapping/tsdf_test_scenes.h"

namespace certislam::slam {
namespace {

using testing::Box;
using testing::DistanceToBoxSurface;
using testing::Pose;
using testing::ScanBoxes;

constexpr double kGround = -1.8;
// Mesh vertices are float32: a vertex mapped by a transform differs from the vertex computed
// in the other frame by float rounding only (coordinates up to ~20 m: ulp ~2e-6).
constexpr double kFloatRounding = 1e-5;

// A drive past the cube: 8 keyframes 1.5 m apart with a slow turn.
std::vector<Eigen::Isometry3d> Drive() {
    std::vector<Eigen::Isometry3d> poses;
    for (int i = 0; i < 8; ++i) poses.push_back(Pose(-2.0 + 1.5 * i, -3.0 + 0.3 * i, 0, 0.1 * i));
    return poses;
}

Eigen::Isometry3d RandomRigid(std::mt19937& rng, double max_angle, double max_shift) {
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = (Eigen::AngleAxisd(max_angle * u(rng), Eigen::Vector3d::UnitZ()) *
                  Eigen::AngleAxisd(max_angle * u(rng), Eigen::Vector3d::UnitX()))
                     .toRotationMatrix();
    T.translation() = max_shift * Eigen::Vector3d(u(rng), u(rng), u(rng));
    return T;
}

TsdfMap BuildMap(int robot, const TsdfMapConfig& cfg, const std::vector<Eigen::Isometry3d>& truth,
                 const std::vector<Eigen::Isometry3d>& estimate) {
    TsdfMap map(robot, cfg);
    const std::vector<Box> scene = testing::GroundAndCube(kGround);
    for (std::size_t i = 0; i < truth.size(); ++i) {
        const auto r = map.Insert(static_cast<int>(i), estimate[i], ScanBoxes(scene, truth[i]));
        EXPECT_EQ(r.status, TsdfMapInsertResult::Status::kIntegrated);
    }
    return map;
}

double MaxVertexDistance(const TriangleMesh& a, const TriangleMesh& b) {
    double worst = 0.0;
    for (std::size_t i = 0; i < a.vertices.size(); ++i) {
        worst = std::max(worst, double((a.vertices[i] - b.vertices[i]).norm()));
    }
    return worst;
}

TEST(TsdfMap, StartsSubmapsByDistanceAndByKeyframeCount) {
    TsdfMapConfig by_distance;
    by_distance.submap_distance_m = 4.0;
    const auto poses = Drive();
    const TsdfMap a = BuildMap(0, by_distance, poses, poses);
    // Anchors at keyframes 0, 3, 6 (each 1.53 m apart: the 3rd step passes 4 m).
    ASSERT_EQ(a.submaps().size(), 3u);
    EXPECT_EQ(a.submaps()[1].anchor, (PoseId{0, 3}));
    EXPECT_EQ(a.submaps()[2].keyframes, (std::vector<int>{6, 7}));

    TsdfMapConfig by_count;
    by_count.submap_max_keyframes = 3;
    const TsdfMap b = BuildMap(1, by_count, poses, poses);
    ASSERT_EQ(b.submaps().size(), 3u);
    EXPECT_EQ(b.submaps()[2].id, (SubmapId{1, 2}));
    EXPECT_EQ(b.submaps()[2].anchor, (PoseId{1, 6}));

    TsdfMapConfig bad;
    bad.submap_distance_m = 0.0;
    EXPECT_THROW(TsdfMap(0, bad), std::invalid_argument);
}

TEST(TsdfMap, SubmapMovedByKnownTransformMovesItsMeshExactly) {
    const auto poses = Drive();
    TsdfMap map = BuildMap(0, TsdfMapConfig{}, poses, poses);
    ASSERT_EQ(map.submaps().size(), 1u);
    const TriangleMesh before = map.ExtractMesh();
    ASSERT_GT(before.triangles.size(), 1000u);
    std::mt19937 rng(11);
    const Eigen::Isometry3d T_delta = RandomRigid(rng, 0.5, 10.0);
    EXPECT_EQ(map.Reanchor([&](const PoseId& id) -> std::optional<Eigen::Isometry3d> {
        return T_delta * poses[static_cast<std::size_t>(id.index)];
    }),
              1u);
    const TriangleMesh after = map.ExtractMesh();
    ASSERT_EQ(after.triangles, before.triangles);
    ASSERT_EQ(after.vertices.size(), before.vertices.size());
    EXPECT_LT(MaxVertexDistance(after, TransformMesh(before, T_delta)), kFloatRounding);
}

// Odometry with a different error per submap (a drift jump at each submap boundary): the
// corrected poses re-anchor the submaps and the map equals the one built on the true poses.
TEST(TsdfMap, SameScansUnderTwoTrajectoriesGiveTheSameMeshAfterReanchoring) {
    TsdfMapConfig cfg;
    cfg.submap_max_keyframes = 2;
    const auto truth = Drive();
    std::vector<Eigen::Isometry3d> drifted;
    std::mt19937 rng(5);
    Eigen::Isometry3d D = Eigen::Isometry3d::Identity();
    for (std::size_t i = 0; i < truth.size(); ++i) {
        if (i % 2 == 0) D = RandomRigid(rng, 0.2, 3.0);
        drifted.push_back(D * truth[i]);
    }
    TsdfMap reference = BuildMap(0, cfg, truth, truth);
    TsdfMap corrected = BuildMap(0, cfg, truth, drifted);
    const TriangleMesh expected = reference.ExtractMesh();
    ASSERT_EQ(corrected.ExtractMesh().vertices.size(), expected.vertices.size());
    EXPECT_GT(MaxVertexDistance(corrected.ExtractMesh(), expected), 0.5);  // wrong before

    EXPECT_EQ(corrected.Reanchor([&](const PoseId& id) -> std::optional<Eigen::Isometry3d> {
        return truth[static_cast<std::size_t>(id.index)];
    }),
              4u);
    const TriangleMesh mesh = corrected.ExtractMesh();
    ASSERT_EQ(mesh.triangles, expected.triangles);
    EXPECT_LT(MaxVertexDistance(mesh, expected), kFloatRounding);
}

TEST(TsdfMap, SubmapBytesRoundTripAndCorruptionIsRejected) {
    const auto poses = Drive();
    const TsdfMap map = BuildMap(3, TsdfMapConfig{}, poses, poses);
    const Submap& s = map.submaps().front();
    const std::string bytes = SerializeSubmap(s);
    std::string error;
    auto back = DeserializeSubmap(bytes, &error);
    ASSERT_TRUE(back.has_value()) << error;
    EXPECT_EQ(back->id, s.id);
    EXPECT_EQ(back->anchor, s.anchor);
    EXPECT_EQ(back->keyframes, s.keyframes);
    EXPECT_TRUE(back->T_world_submap.isApprox(s.T_world_submap, 0.0));
    EXPECT_TRUE(back->volume.SameVoxels(s.volume));
    EXPECT_LT(bytes.size(), s.volume.Stats().memory_bytes / 2);  // compressed

    EXPECT_FALSE(DeserializeSubmap(bytes.substr(0, 40), &error));
    std::string bad_pose = bytes;
    bad_pose[31] = char(bad_pose[31] ^ 0x40);  // exponent of the rotation's first entry
    EXPECT_FALSE(DeserializeSubmap(bad_pose, &error));
    EXPECT_NE(error.find("rigid"), std::string::npos) << error;
    std::string bad_volume = bytes;
    bad_volume.resize(bytes.size() - 10);
    EXPECT_FALSE(DeserializeSubmap(bad_volume, &error));
}

// Two robots map the scene from opposite sides; robot 1's submap travels as bytes, and the
// fused volume in one frame holds both sides of the cube within a voxel of the truth.
TEST(TsdfMap, FusesTwoRobotsSubmapsIntoOneFrame) {
    const std::vector<Box> scene = testing::GroundAndCube(kGround);
    TsdfMap robot0(0), robot1(1);
    robot0.Insert(0, Pose(0, -2, 0, 0.0), ScanBoxes(scene, Pose(0, -2, 0, 0.0)));
    robot0.Insert(1, Pose(2, 5, 0, -1.0), ScanBoxes(scene, Pose(2, 5, 0, -1.0)));
    robot1.Insert(0, Pose(9, -1, 0, 2.0), ScanBoxes(scene, Pose(9, -1, 0, 2.0)));
    robot1.Insert(1, Pose(8, 4, 0, -2.5), ScanBoxes(scene, Pose(8, 4, 0, -2.5)));
    std::string error;
    auto received = DeserializeSubmap(SerializeSubmap(robot1.submaps().front()), &error);
    ASSERT_TRUE(received.has_value()) << error;
    robot0.AddSubmap(std::move(*received));
    ASSERT_EQ(robot0.submaps().size(), 2u);

    const TsdfConfig cfg;
    TsdfVolume fused = robot0.Fuse(cfg);
    const TriangleMesh mesh = fused.ExtractMesh();
    int near_minus_x = 0, near_plus_x = 0;
    double worst = 0.0;
    for (const auto& p : mesh.vertices) {
        const Eigen::Vector3d q = p.cast<double>();
        worst =
            std::max(worst, std::min(std::abs(q.z() - kGround), DistanceToBoxSurface(scene[1], q)));
        near_minus_x += std::abs(q.x() - 4.0) < 0.1 && q.z() > -1.0 ? 1 : 0;
        near_plus_x += std::abs(q.x() - 6.0) < 0.1 && q.z() > -1.0 ? 1 : 0;
    }
    // Resampling to the nearest voxel adds up to half a voxel to the half-voxel surface bound.
    EXPECT_LT(worst, cfg.voxel_size_m);
    EXPECT_GT(near_minus_x, 20);  // seen by robot 0 only
    EXPECT_GT(near_plus_x, 20);   // seen by robot 1 only
}

// Fusing and meshing slab by slab gives exactly the mesh of the whole fused volume, whatever
// the slab width (here down to one block, so blocks, cubes and welds cross slab borders).
TEST(TsdfMap, FusedMeshBySlabsEqualsTheMeshOfTheFusedVolume) {
    const std::vector<Box> scene = testing::GroundAndCube(kGround);
    TsdfMapConfig cfg;
    cfg.submap_max_keyframes = 2;
    const auto poses = Drive();
    TsdfMap map = BuildMap(0, cfg, poses, poses);
    const TsdfMap peer = BuildMap(1, cfg, {Pose(9, -1, 0, 2.0)}, {Pose(9, -1, 0, 2.0)});
    std::string error;
    map.AddSubmap(*DeserializeSubmap(SerializeSubmap(peer.submaps()[0]), &error));
    ASSERT_GT(map.submaps().size(), 2u);
    // Closed submaps are packed: slabs fuse them from their voxel lists, Fuse from their grids.
    ASSERT_TRUE(map.submaps()[0].volume.packed());
    TsdfConfig fused_config;
    fused_config.voxel_size_m = 0.15;  // not the submaps' voxel: resampled
    const TriangleMesh whole = map.Fuse(fused_config).ExtractMesh();
    ASSERT_GT(whole.triangles.size(), 1000u);
    std::vector<TsdfVolume::FusePart> parts;
    for (const Submap& s : map.submaps()) parts.push_back({&s.volume, s.T_world_submap});
    for (const int blocks : {1, 3, 1000}) {
        const TriangleMesh slabs = blocks == 1000
                                       ? map.FusedMesh(fused_config)
                                       : TsdfVolume::FuseAndMesh(parts, fused_config, blocks);
        ASSERT_EQ(slabs.vertices.size(), whole.vertices.size()) << blocks;
        EXPECT_EQ(slabs.triangles, whole.triangles) << blocks;
        EXPECT_EQ(MaxVertexDistance(slabs, whole), 0.0) << blocks;
    }
    // In pieces, run in reverse order or on threads, and welded in order: still the same mesh
    // (the pieces' vertices on shared grid edges are kept once).
    const TsdfVolume::RunPieces reverse = [](int n, const std::function<void(int)>& piece) {
        for (int k = n - 1; k >= 0; --k) piece(k);
    };
    const TsdfVolume::RunPieces threads = [](int n, const std::function<void(int)>& piece) {
        std::vector<std::future<void>> all;
        for (int k = 0; k < n; ++k) all.push_back(std::async(std::launch::async, piece, k));
        for (auto& f : all) f.get();
    };
    for (const int pieces : {2, 3, 7, 1000}) {  // 1000: more pieces than slabs (capped)
        for (const auto* run : {&reverse, &threads}) {
            if (pieces == 1000 && run == &threads) continue;
            const TriangleMesh meshed =
                TsdfVolume::FuseAndMesh(parts, fused_config, 1, pieces, *run);
            ASSERT_EQ(meshed.vertices.size(), whole.vertices.size()) << pieces;
            EXPECT_EQ(meshed.triangles, whole.triangles) << pieces;
            EXPECT_EQ(MaxVertexDistance(meshed, whole), 0.0) << pieces;
        }
    }
    EXPECT_EQ(map.FusedMesh(fused_config, 2, threads).triangles, whole.triangles);
}

TEST(TsdfMap, KeepsWithinItsMemoryBudgetByCoarseningThenSkipping) {
    const std::vector<Box> scene = testing::GroundAndCube(kGround);
    TsdfMapConfig free_config;
    free_config.memory_budget_mb = 0.0;    // no budget
    free_config.submap_max_keyframes = 1;  // every scan its own volume: memory grows per scan
    free_config.tsdf.voxel_size_m = 0.1;
    free_config.pack_closed_submaps = false;  // live volumes: packed ones are the next test's
    const auto poses = Drive();
    TsdfMap free(0, free_config);
    for (std::size_t i = 0; i < poses.size(); ++i) {
        free.Insert(static_cast<int>(i), poses[i], ScanBoxes(scene, poses[i]));
    }
    std::size_t one_scan = 0;  // the largest one-scan volume
    for (const Submap& s : free.submaps()) {
        one_scan = std::max(one_scan, s.volume.Stats().memory_bytes);
    }
    EXPECT_EQ(free.Budget().coarsenings, 0);

    TsdfMapConfig bounded = free_config;
    bounded.memory_budget_mb = 2.5 * static_cast<double>(one_scan) / (1024.0 * 1024.0);
    bounded.max_coarsening = 1;
    TsdfMap map(0, bounded);
    std::vector<TsdfMapInsertResult::Status> status;
    for (int round = 0; round < 2; ++round) {
        for (std::size_t i = 0; i < poses.size(); ++i) {
            const int index = round * static_cast<int>(poses.size()) + static_cast<int>(i);
            status.push_back(map.Insert(index, poses[i], ScanBoxes(scene, poses[i])).status);
        }
    }
    const TsdfMapBudget budget = map.Budget();
    EXPECT_EQ(budget.coarsenings, 1);
    EXPECT_DOUBLE_EQ(budget.voxel_size_m, 0.2);
    EXPECT_GT(budget.skipped_scans, 0);
    EXPECT_EQ(std::count(status.begin(), status.end(), TsdfMapInsertResult::Status::kOverBudget),
              budget.skipped_scans);
    // Checked before each insert: at most one scan's volume over the budget, not 16 scans' worth.
    EXPECT_LE(static_cast<double>(budget.memory_bytes),
              bounded.memory_budget_mb * 1024.0 * 1024.0 + static_cast<double>(one_scan));
    EXPECT_LT(budget.memory_bytes, free.Budget().memory_bytes * 2);  // free: 16 scans ~ 2x this
    // The coarser submaps still hold the scene: their voxel is the doubled one.
    EXPECT_DOUBLE_EQ(map.submaps().back().volume.config().voxel_size_m, 0.2);

    TsdfMapConfig bad;
    bad.memory_budget_mb = -1.0;
    EXPECT_THROW(TsdfMap(0, bad), std::invalid_argument);
}

// Closed and received submaps kept as their compressed bytes give the same voxels, meshes and
// fused volume as live ones, and the budget counts the bytes held.
TEST(TsdfMap, PackedSubmapsGiveTheSameMapAndCountTheirBytes) {
    const std::vector<Box> scene = testing::GroundAndCube(kGround);
    TsdfMapConfig live_config;
    live_config.submap_max_keyframes = 3;  // 8 scans: 3 submaps, the first two closed
    live_config.pack_closed_submaps = false;
    TsdfMapConfig packed_config = live_config;
    packed_config.pack_closed_submaps = true;
    const auto poses = Drive();
    const TsdfMap live = BuildMap(0, live_config, poses, poses);
    TsdfMap packed = BuildMap(0, packed_config, poses, poses);
    ASSERT_EQ(packed.submaps().size(), 3u);
    std::size_t held = 0, live_bytes = 0;
    for (std::size_t i = 0; i < 3; ++i) {
        const TsdfVolume& v = packed.submaps()[i].volume;
        EXPECT_EQ(v.packed(), i < 2) << "submap " << i;  // the active one stays live
        EXPECT_TRUE(v.SameVoxels(live.submaps()[i].volume)) << "submap " << i;
        EXPECT_EQ(v.Stats().active_voxels, live.submaps()[i].volume.Stats().active_voxels);
        held += v.Stats().memory_bytes;
        if (i < 2) {
            EXPECT_LT(v.Stats().memory_bytes, v.Serialize().size());  // zstd on top
        }
        live_bytes += live.submaps()[i].volume.Stats().memory_bytes;
    }
    EXPECT_EQ(packed.Budget().memory_bytes, held);
    EXPECT_LT(held, live_bytes);

    // A peer's submap arrives packed and stays packed through meshing and fusion.
    TsdfMap peer(1, packed_config);
    peer.Insert(0, Pose(9, -1, 0, 2.0), ScanBoxes(scene, Pose(9, -1, 0, 2.0)));
    std::string error;
    auto received = DeserializeSubmap(SerializeSubmap(peer.submaps().front()), &error, true);
    ASSERT_TRUE(received.has_value()) << error;
    EXPECT_TRUE(received->volume.packed());
    EXPECT_TRUE(received->volume.SameVoxels(peer.submaps().front().volume));
    const TsdfStats got = received->volume.Stats(), sent = peer.submaps().front().volume.Stats();
    EXPECT_EQ(got.active_voxels, sent.active_voxels);  // counted from the bytes, not the grids
    EXPECT_EQ(got.leaf_blocks, sent.leaf_blocks);
    EXPECT_EQ(got.allocated_voxels, sent.allocated_voxels);
    TsdfMap live_team = BuildMap(0, live_config, poses, poses);
    live_team.AddSubmap(*DeserializeSubmap(SerializeSubmap(peer.submaps().front()), &error));
    packed.AddSubmap(std::move(*received));

    const TriangleMesh a = live_team.ExtractMesh(), b = packed.ExtractMesh();
    ASSERT_EQ(a.triangles, b.triangles);
    EXPECT_EQ(MaxVertexDistance(a, b), 0.0);
    EXPECT_TRUE(live_team.Fuse(TsdfConfig{}).SameVoxels(packed.Fuse(TsdfConfig{})));
    for (const Submap& s : packed.submaps())
        EXPECT_EQ(s.volume.packed(), s.id.robot == 1 || s.id.index < 2);
    // Writing into a packed volume unpacks it; its voxels are the same as before.
    TsdfVolume v = packed.submaps().front().volume.Clone();
    ASSERT_TRUE(v.packed());
    v.Integrate(ScanBoxes(scene, poses[0]), Eigen::Isometry3d::Identity());
    EXPECT_FALSE(v.packed());
    TsdfVolume w = live.submaps().front().volume.Clone();
    w.Integrate(ScanBoxes(scene, poses[0]), Eigen::Isometry3d::Identity());
    EXPECT_TRUE(v.SameVoxels(w));
}

}  // namespace
}  // namespace certislam::slam
