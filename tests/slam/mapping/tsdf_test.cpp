// Tests of the sparse TSDF: marching-cubes table, surface accuracy on a plane and a box,
// sparsity, serialisation and incremental meshing.
#include "slam/mapping/tsdf.h"

#include <gtest/gtest.h>

#include <map>
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
constexpr double kHalfVoxel = 0.5;  // the accuracy bound, in voxels

// Polygonises a dense grid of values with the case table; a vertex is named by its grid edge.
struct DenseMesh {
    std::vector<Eigen::Vector3i> triangles;
    std::map<std::array<int, 4>, int> vertex_of_edge;
    std::vector<Eigen::Vector3d> vertices;
};

DenseMesh PolygoniseDense(const std::vector<double>& v, int n) {
    DenseMesh m;
    auto at = [&](int x, int y, int z) { return v[(x * n + y) * n + z]; };
    for (int x = 0; x + 1 < n; ++x) {
        for (int y = 0; y + 1 < n; ++y) {
            for (int z = 0; z + 1 < n; ++z) {
                int ci = 0;
                std::array<double, 8> s;
                for (int c = 0; c < 8; ++c) {
                    s[c] = at(x + (c & 1), y + ((c >> 1) & 1), z + (c >> 2));
                    ci |= (s[c] < 0 ? 1 : 0) << c;
                }
                auto vertex = [&](int e) {
                    const int b = CubeEdgeBase(e), tip = CubeEdgeTip(e), axis = e / 4;
                    const std::array<int, 4> key = {x + (b & 1), y + ((b >> 1) & 1), z + (b >> 2),
                                                    axis};
                    auto [it, fresh] = m.vertex_of_edge.emplace(key, int(m.vertices.size()));
                    if (fresh) {
                        Eigen::Vector3d p(key[0], key[1], key[2]);
                        p[axis] += s[b] / (s[b] - s[tip]);
                        m.vertices.push_back(p);
                    }
                    return it->second;
                };
                for (const auto& t : CubeCaseTriangles(ci)) {
                    m.triangles.emplace_back(vertex(t[0]), vertex(t[1]), vertex(t[2]));
                }
            }
        }
    }
    return m;
}

double SignedVolume(const DenseMesh& m) {
    double vol = 0.0;
    for (const auto& t : m.triangles) {
        vol += m.vertices[t[0]].dot(m.vertices[t[1]].cross(m.vertices[t[2]])) / 6.0;
    }
    return vol;
}

TEST(MarchingCubesCases, RandomFieldGivesClosedConsistentlyWoundSurface) {
    constexpr int kN = 14;
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    std::vector<double> v(kN * kN * kN);
    for (int x = 0; x < kN; ++x) {
        for (int y = 0; y < kN; ++y) {
            for (int z = 0; z < kN; ++z) {
                const bool border =
                    x == 0 || y == 0 || z == 0 || x == kN - 1 || y == kN - 1 || z == kN - 1;
                v[(x * kN + y) * kN + z] = border ? 1.0 : u(rng);
            }
        }
    }
    const DenseMesh m = PolygoniseDense(v, kN);
    ASSERT_GT(m.triangles.size(), 1000u);
    // Closed and consistently wound: each directed edge once, and its reverse exactly once.
    std::map<std::pair<int, int>, int> directed;
    for (const auto& t : m.triangles) {
        for (int k = 0; k < 3; ++k) ++directed[{t[k], t[(k + 1) % 3]}];
    }
    // (An edge may be used twice each way where two cubes' fans share a diagonal.)
    for (const auto& [e, count] : directed) {
        const auto reverse = directed.find({e.second, e.first});
        ASSERT_NE(reverse, directed.end());
        ASSERT_EQ(reverse->second, count);
    }
}

TEST(MarchingCubesCases, SphereHasOutwardNormalsAndItsVolume) {
    constexpr int kN = 24;
    constexpr double kRadius = 8.0, kVolumeTolerance = 0.02;
    std::vector<double> v(kN * kN * kN);
    for (int x = 0; x < kN; ++x) {
        for (int y = 0; y < kN; ++y) {
            for (int z = 0; z < kN; ++z) {
                v[(x * kN + y) * kN + z] =
                    (Eigen::Vector3d(x, y, z) - Eigen::Vector3d::Constant(11.5)).norm() - kRadius;
            }
        }
    }
    const double expected = 4.0 / 3.0 * std::numbers::pi * kRadius * kRadius * kRadius;
    EXPECT_NEAR(SignedVolume(PolygoniseDense(v, kN)), expected, kVolumeTolerance * expected);
}

std::vector<Eigen::Isometry3d> ScanPoses() {
    return {Pose(0, -2, 0, 0.0), Pose(3, -4, 0, 0.7), Pose(9, -1, 0, 2.0), Pose(8, 4, 0, -2.5),
            Pose(2, 5, 0, -1.0)};
}

TsdfVolume IntegrateScene(const std::vector<Box>& scene, const TsdfConfig& cfg) {
    TsdfVolume volume(cfg);
    for (const auto& T : ScanPoses()) {
        const auto r = volume.Integrate(ScanBoxes(scene, T), T);
        EXPECT_EQ(r.status, TsdfIntegrateResult::Status::kOk);
    }
    return volume;
}

struct AccuracyCase {
    double voxel_m;
    bool grouped;
};

// Per-point rays meet the bound everywhere. Grouped rays (one ray per end voxel to the
// points' mean) trade a little accuracy at depth discontinuities (cube edges, where a voxel's
// points come from two surfaces) for speed: there we require the bound for all but 1 % of
// the vertices and bound the rest by kGroupedWorstVoxels.
constexpr double kGroupedOutlierFraction = 0.01;
constexpr double kGroupedWorstVoxels = 1.5;

// Checks the distances of the mesh vertices to the truth against the bounds above.
void ExpectWithinHalfVoxel(const std::vector<double>& distances, const AccuracyCase& c) {
    ASSERT_FALSE(distances.empty());
    const double bound = kHalfVoxel * c.voxel_m;
    const double worst = *std::max_element(distances.begin(), distances.end());
    const auto outside =
        std::count_if(distances.begin(), distances.end(), [&](double d) { return d >= bound; });
    if (!c.grouped) {
        EXPECT_LT(worst, bound);
        return;
    }
    EXPECT_LE(double(outside), kGroupedOutlierFraction * distances.size());
    EXPECT_LT(worst, kGroupedWorstVoxels * c.voxel_m);
}

class TsdfAccuracy : public ::testing::TestWithParam<AccuracyCase> {};

TEST_P(TsdfAccuracy, PlaneSurfaceWithinHalfVoxel) {
    TsdfConfig cfg;
    cfg.voxel_size_m = GetParam().voxel_m;
    cfg.group_points_by_voxel = GetParam().grouped;
    TsdfVolume volume = IntegrateScene({Box{{-200, -200, -50}, {200, 200, kGround}}}, cfg);
    const TriangleMesh mesh = volume.ExtractMesh();
    ASSERT_GT(mesh.vertices.size(), 500u);
    std::vector<double> distances;
    for (const auto& p : mesh.vertices) distances.push_back(std::abs(p.z() - kGround));
    ExpectWithinHalfVoxel(distances, GetParam());
}

TEST_P(TsdfAccuracy, BoxSurfaceWithinHalfVoxel) {
    TsdfConfig cfg;
    cfg.voxel_size_m = GetParam().voxel_m;
    cfg.group_points_by_voxel = GetParam().grouped;
    const std::vector<Box> scene = testing::GroundAndCube(kGround);
    TsdfVolume volume = IntegrateScene(scene, cfg);
    const TriangleMesh mesh = volume.ExtractMesh();
    std::vector<double> distances;
    int on_cube = 0;
    for (const auto& p : mesh.vertices) {
        const Eigen::Vector3d q = p.cast<double>();
        const double d_ground = std::abs(q.z() - kGround);
        const double d_cube = DistanceToBoxSurface(scene[1], q);
        distances.push_back(std::min(d_ground, d_cube));
        on_cube += d_cube < d_ground ? 1 : 0;
    }
    ExpectWithinHalfVoxel(distances, GetParam());
    EXPECT_GT(on_cube, 50);  // the cube is in the mesh, not only the ground
}

INSTANTIATE_TEST_SUITE_P(VoxelSizes, TsdfAccuracy,
                         ::testing::Values(AccuracyCase{0.1, false}, AccuracyCase{0.2, false},
                                           AccuracyCase{0.5, false}, AccuracyCase{0.1, true},
                                           AccuracyCase{0.2, true}, AccuracyCase{0.5, true}),
                         [](const auto& info) {
                             return "Voxel" + std::to_string(int(info.param.voxel_m * 100)) + "cm" +
                                    (info.param.grouped ? "Grouped" : "PerPoint");
                         });

TEST(Tsdf, AllocatesOnlyNearSurfacesNoFreeSpaceCarving) {
    TsdfConfig cfg;
    TsdfVolume volume = IntegrateScene(testing::GroundAndCube(kGround), cfg);
    // Free space crossed by many rays, far (> truncation) from every surface: never touched.
    EXPECT_FALSE(volume.Query({2.0, -2.0, 0.0}).has_value());
    EXPECT_FALSE(volume.Query({0.0, 0.0, -0.5}).has_value());
    // Just in front of the cube's -x face: observed, positive, within the truncation.
    const auto front = volume.Query({3.8, 1.0, -1.0});
    ASSERT_TRUE(front.has_value());
    EXPECT_GT(front->sdf_m, 0.0f);
    EXPECT_LE(front->sdf_m, cfg.truncation_m() + 1e-6);
    const TsdfStats s = volume.Stats();
    EXPECT_GT(s.active_voxels, 0u);
    EXPECT_LE(s.active_voxels, s.allocated_voxels);
    EXPECT_GT(s.memory_bytes, s.active_voxels * 8);  // two floats per voxel at least
}

TEST(Tsdf, SerialisationRoundTripIsVoxelExactAndCorruptionIsRejected) {
    TsdfVolume volume = IntegrateScene(testing::GroundAndCube(kGround), TsdfConfig{});
    const std::string bytes = volume.Serialize();
    std::string error;
    auto back = TsdfVolume::Deserialize(bytes, &error);
    ASSERT_TRUE(back.has_value()) << error;
    EXPECT_TRUE(back->SameVoxels(volume));
    const TriangleMesh a = volume.ExtractMesh(), b = back->ExtractMesh();
    ASSERT_EQ(a.vertices.size(), b.vertices.size());
    for (size_t i = 0; i < a.vertices.size(); ++i) ASSERT_EQ(a.vertices[i], b.vertices[i]);
    // Compressed: smaller than the grids in memory.
    EXPECT_LT(bytes.size(), volume.Stats().memory_bytes);

    EXPECT_FALSE(TsdfVolume::Deserialize(bytes.substr(0, bytes.size() / 2), &error));
    EXPECT_NE(error.find("length"), std::string::npos);
    std::string bad_magic = bytes;
    bad_magic[0] = 'X';
    EXPECT_FALSE(TsdfVolume::Deserialize(bad_magic, &error));
    std::string garbage = bytes;
    for (size_t i = 80; i < garbage.size(); i += 7) garbage[i] = char(garbage[i] ^ 0x5A);
    EXPECT_FALSE(TsdfVolume::Deserialize(garbage, &error).has_value());
}

TEST(Tsdf, IncrementalMeshEqualsFullRemesh) {
    const std::vector<Box> scene = testing::GroundAndCube(kGround);
    TsdfVolume volume(TsdfConfig{});
    size_t full_blocks = 0;
    for (const auto& T : ScanPoses()) {
        volume.Integrate(ScanBoxes(scene, T), T);
        const TriangleMesh incremental = volume.ExtractMesh();
        auto fresh = TsdfVolume::Deserialize(volume.Serialize(), nullptr);  // all blocks dirty
        ASSERT_TRUE(fresh.has_value());
        const TriangleMesh full = fresh->ExtractMesh();
        full_blocks = fresh->last_remeshed_blocks();
        ASSERT_EQ(incremental.vertices, full.vertices);
        ASSERT_EQ(incremental.triangles, full.triangles);
    }
    // A scan from where the volume has already seen everything re-meshes only touched blocks.
    const Eigen::Isometry3d T = ScanPoses().front();
    volume.Integrate(ScanBoxes(scene, T, 8, 90, 6.0), T);
    volume.ExtractMesh();
    EXPECT_LT(volume.last_remeshed_blocks(), full_blocks);
}

TEST(TsdfConfig, ValidateNamesFieldValueAndRule) {
    TsdfConfig cfg;
    cfg.voxel_size_m = 0.0;
    try {
        cfg.Validate();
        FAIL() << "expected std::invalid_argument";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("voxel_size_m"), std::string::npos);
    }
    TsdfConfig thin;
    thin.truncation_voxels = 0.5;
    EXPECT_THROW(TsdfVolume{thin}, std::invalid_argument);
}

}  // namespace
}  // namespace certislam::slam
