// Loop verification: GICP on real pairs against reference poses, Scan Context yaw seeding,
// the degeneracy check on a synthetic corridor, and rejection of different places.
#include "slam/frontend/registration.h"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>

#include <array>
#include <cmath>
#include <fstream>
#include <map>
#include <numbers>
#include <optional>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>

#include "slam/frontend/downsample.h"
#include "slam/frontend/gicp_cycle.h"
#include "slam/frontend/point_kdtree.h"
#include "slam/frontend/registration_quality.h"
#include "slam/frontend/scan_context.h"
#include "slam/io/cloud_io.h"
#include "tests/data_paths.h"

namespace certislam::slam {
namespace {

const std::string kLidar = test_data::DataPath("lidar/");
constexpr double kHdlMaxTranslationM = 0.05;  // fast_gicp's own test thresholds (issue 4)
constexpr double kHdlMaxRotationDeg = 1.0;
constexpr double kKittiMaxTranslationM = 0.10;
constexpr double kKittiMaxRotationDeg = 0.5;

PointCloud Load(const std::string& relative) {
    CloudReadResult r = ReadCloud(kLidar + relative);
    EXPECT_TRUE(r.ok()) << r.error;
    return std::move(r.cloud);
}

// Reads KITTI-style 3x4 poses, one per line: skips '#' comments, a leading label ("Tr:") and a
// leading frame index (13 numbers on a line).
std::vector<Eigen::Isometry3d> ReadKittiPoses(const std::string& path) {
    std::ifstream in(path);
    EXPECT_TRUE(in.good()) << path;
    std::vector<Eigen::Isometry3d> poses;
    std::string line;
    while (std::getline(in, line)) {
        if (line.empty() || line[0] == '#') continue;
        std::istringstream fields(line);
        std::vector<double> values;
        std::string token;
        while (fields >> token) {
            if (token.back() == ':') continue;
            values.push_back(std::stod(token));
        }
        if (values.size() != 12 && values.size() != 13) continue;
        const std::size_t first = values.size() - 12;
        Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
        for (int k = 0; k < 12; ++k) T.matrix()(k / 4, k % 4) = values[first + k];
        poses.push_back(T);
    }
    return poses;
}

Eigen::Isometry3d ReadMatrix4(const std::string& path) {
    std::ifstream in(path);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    for (int k = 0; k < 16; ++k) in >> T.matrix()(k / 4, k % 4);
    return T;
}

double TranslationError(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
    return (a.inverse() * b).translation().norm();
}

double RotationErrorDeg(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
    return Eigen::AngleAxisd((a.inverse() * b).rotation()).angle() * 180.0 / std::numbers::pi;
}

PointCloud Transform(const PointCloud& cloud, const Eigen::Isometry3d& T) {
    const Eigen::Isometry3f Tf = T.cast<float>();
    PointCloud out;
    for (const auto& p : cloud) out.push_back(Tf * p);
    return out;
}

TEST(Registration, HdlPairWithinFiveCentimetresAndOneDegree) {
    const PointCloud target = Load("hdl_pair_fast_gicp/251370668.pcd");
    const PointCloud source = Load("hdl_pair_fast_gicp/251371071.pcd");
    const Eigen::Isometry3d reference = ReadMatrix4(kLidar + "hdl_pair_fast_gicp/relative.txt");
    RegistrationConfig config;
    config.voxel_m = 0.2;
    const RegistrationResult r =
        RegisterScans(source, target, Eigen::Isometry3d::Identity(), config);
    EXPECT_TRUE(r.accepted()) << static_cast<int>(r.status);
    EXPECT_TRUE(r.converged);
    EXPECT_LT(TranslationError(r.T_target_source, reference), kHdlMaxTranslationM);
    EXPECT_LT(RotationErrorDeg(r.T_target_source, reference), kHdlMaxRotationDeg);
    EXPECT_GT(r.fitness, 0.8);
    EXPECT_GT(r.kappa, 0.0);
    EXPECT_GT(r.tau, 0.0);
    EXPECT_TRUE(r.information.isApprox(r.information.transpose(), 1e-9));
    EXPECT_GT(Eigen::SelfAdjointEigenSolver<Information6>(r.information).eigenvalues().minCoeff(),
              0.0);
    // The floor bounds the information: sigma_t >= 5 cm means tau <= 1 / 0.05^2.
    EXPECT_LE(r.tau, 1.0 / (config.min_translation_sigma_m * config.min_translation_sigma_m));
}

// KITTI 00 frames 94 -> 95 (0.47 m apart): GT relative pose from the KITTI poses and the
// velodyne-to-camera calibration, T_world_velo = T_world_cam0 * Tr.
TEST(Registration, KittiConsecutiveScansMatchGroundTruth) {
    const auto poses = ReadKittiPoses(kLidar + "kitti00_scancontext_samples/poses_cam0_subset.txt");
    ASSERT_EQ(poses.size(), 4u);
    const Eigen::Isometry3d Tr =
        ReadKittiPoses(kLidar + "kitti00_scancontext_samples/calib_Tr_velo_to_cam0_seq00.txt")
            .at(0);
    const Eigen::Isometry3d truth = (poses[0] * Tr).inverse() * (poses[1] * Tr);  // T_94_95
    const PointCloud target = Load("kitti00_scancontext_samples/velodyne/000094.bin");
    const PointCloud source = Load("kitti00_scancontext_samples/velodyne/000095.bin");
    const ScanContextConfig sc;
    const ScanContextMatch m =
        ScanContextDistance(MakeScanContext(source, sc), MakeScanContext(target, sc));
    const RegistrationResult r =
        RegisterScans(source, target, YawGuess(m.yaw_rad), RegistrationConfig{});
    EXPECT_TRUE(r.accepted()) << static_cast<int>(r.status);
    EXPECT_LT(TranslationError(r.T_target_source, truth), kKittiMaxTranslationM);
    EXPECT_LT(RotationErrorDeg(r.T_target_source, truth), kKittiMaxRotationDeg);
}

// A KAIST03 pair 3 keyframes (~3.5 m) apart with the source spun by 150 degrees: only the
// Scan Context yaw makes the seed good enough.
TEST(Registration, ScanContextYawSeedRecoversLargeRotation) {
    const auto poses = ReadKittiPoses(kLidar + "mulran_kaist03_keyframes/optimized_poses.txt");
    const Eigen::Isometry3d spin = YawGuess(150.0 * std::numbers::pi / 180.0);
    const Eigen::Isometry3d truth = poses[0].inverse() * poses[3] * spin.inverse();
    const PointCloud target = Load("mulran_kaist03_keyframes/Scans/000000.pcd");
    const PointCloud source = Transform(Load("mulran_kaist03_keyframes/Scans/000003.pcd"), spin);
    const ScanContextConfig sc;
    const ScanContextMatch m =
        ScanContextDistance(MakeScanContext(source, sc), MakeScanContext(target, sc));
    const RegistrationResult r =
        RegisterScans(source, target, YawGuess(m.yaw_rad), RegistrationConfig{});
    EXPECT_TRUE(r.accepted()) << static_cast<int>(r.status);
    EXPECT_LT(TranslationError(r.T_target_source, truth), kKittiMaxTranslationM);
    EXPECT_LT(RotationErrorDeg(r.T_target_source, truth), 1.0);
}

TEST(Registration, DifferentPlacesAreNotAccepted) {
    const PointCloud target = Load("kitti00_scancontext_samples/velodyne/000094.bin");
    const PointCloud source = Load("kitti00_scancontext_samples/velodyne/000198.bin");
    const RegistrationResult r =
        RegisterScans(source, target, Eigen::Isometry3d::Identity(), RegistrationConfig{});
    EXPECT_FALSE(r.accepted());
}

// Points on planes: a floor, and walls at |y| = 2 along x (a corridor); with `end_walls`, also
// walls at |x| = 15 closing it into a room.
PointCloud Corridor(bool end_walls, std::uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> along(-15.0f, 15.0f), across(-2.0f, 2.0f), up(0.0f, 3.0f);
    std::normal_distribution<float> noise(0.0f, 0.01f);
    PointCloud cloud;
    for (int i = 0; i < 20000; ++i) {
        cloud.emplace_back(along(rng), across(rng), noise(rng));                       // floor
        cloud.emplace_back(along(rng), (i % 2 ? 2.0f : -2.0f) + noise(rng), up(rng));  // walls
        if (end_walls && i % 4 == 0) {
            cloud.emplace_back((i % 8 ? 15.0f : -15.0f) + noise(rng), across(rng), up(rng));
        }
    }
    return cloud;
}

TEST(Registration, CorridorIsRejectedAsDegenerate) {
    const Eigen::Isometry3d offset(Eigen::Translation3d(0.3, 0.0, 0.0));
    const PointCloud target = Corridor(false, 1);
    const PointCloud source = Transform(Corridor(false, 2), offset);
    const RegistrationResult r =
        RegisterScans(source, target, Eigen::Isometry3d::Identity(), RegistrationConfig{});
    EXPECT_EQ(r.status, RegistrationResult::Status::kDegenerate) << r.translation_eigen_ratio;
    EXPECT_LT(r.translation_eigen_ratio, 0.01);
    // The unconstrained direction keeps little information: at most the floor's 1/sigma^2.
    EXPECT_LT(r.information(0, 0), 1.01 / (0.05 * 0.05));
}

TEST(Registration, ClosedRoomIsAccepted) {
    const Eigen::Isometry3d offset(Eigen::Translation3d(0.3, -0.1, 0.0));
    const PointCloud target = Corridor(true, 1);
    const PointCloud source = Transform(Corridor(true, 2), offset);
    const RegistrationResult r =
        RegisterScans(source, target, Eigen::Isometry3d::Identity(), RegistrationConfig{});
    EXPECT_TRUE(r.accepted()) << static_cast<int>(r.status) << " " << r.translation_eigen_ratio;
    EXPECT_LT(TranslationError(r.T_target_source, offset.inverse()), 0.03);
}

TEST(Registration, EmptyCloudIsTooFewPoints) {
    const PointCloud target = Corridor(true, 1);
    const RegistrationResult r =
        RegisterScans({}, target, Eigen::Isometry3d::Identity(), RegistrationConfig{});
    EXPECT_EQ(r.status, RegistrationResult::Status::kTooFewPoints);
}

// Prepared clouds reused across registrations (as the loop matcher keeps them) give what
// registering the raw clouds gives, both ways round.
TEST(Registration, PreparedCloudsReusedGiveTheSameResult) {
    const PointCloud a = Load("hdl_pair_fast_gicp/251370668.pcd");
    const PointCloud b = Load("hdl_pair_fast_gicp/251371071.pcd");
    RegistrationConfig config;
    config.voxel_m = 0.4;
    const PreparedCloud prepared_a(a, config), prepared_b(b, config);
    EXPECT_TRUE(prepared_a.PreparedFor(config));
    for (int round = 0; round < 2; ++round) {
        const auto I = Eigen::Isometry3d::Identity();
        const RegistrationResult plain = RegisterScans(b, a, I, config);
        const RegistrationResult prepared = RegisterScans(prepared_b, prepared_a, I, config);
        EXPECT_EQ(prepared.status, plain.status);
        EXPECT_TRUE(prepared.T_target_source.isApprox(plain.T_target_source, 1e-12));
        EXPECT_DOUBLE_EQ(prepared.fitness, plain.fitness);
        EXPECT_DOUBLE_EQ(prepared.tau, plain.tau);
        const RegistrationResult back = RegisterScans(prepared_a, prepared_b, I, config);
        EXPECT_TRUE(
            back.T_target_source.isApprox(RegisterScans(a, b, I, config).T_target_source, 1e-12));
    }
    // A cloud prepared as a source only (no local planes) gives the same result as a source.
    const PreparedCloud source_b(b, config, /*as_target=*/false);
    EXPECT_TRUE(prepared_a.PreparedAsTarget());
    EXPECT_FALSE(source_b.PreparedAsTarget());
    const auto I = Eigen::Isometry3d::Identity();
    const RegistrationResult full = RegisterScans(prepared_b, prepared_a, I, config);
    const RegistrationResult lean = RegisterScans(source_b, prepared_a, I, config);
    EXPECT_EQ(lean.status, full.status);
    EXPECT_TRUE(lean.T_target_source.isApprox(full.T_target_source, 1e-12));
    EXPECT_DOUBLE_EQ(lean.fitness, full.fitness);
    EXPECT_DOUBLE_EQ(lean.inlier_rmse_m, full.inlier_rmse_m);
    EXPECT_DOUBLE_EQ(lean.tau, full.tau);
    EXPECT_TRUE(lean.information.isApprox(full.information, 1e-12));
    config.voxel_m = 0.3;
    EXPECT_FALSE(prepared_a.PreparedFor(config));
}

// GICP's cycle test: an iterate back where it was 2 to 4 steps before closes a cycle, converged
// only when the cycle's iterates lie within the tight tolerance; a steady crawl and a cycle longer
// than 4 close nothing.
TEST(Registration, GicpCycleTellsAClosedCycleFromACrawl) {
    const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
    const Eigen::Matrix3d turn =
        Eigen::AngleAxisd(2e-4, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    const auto at = [](double x) { return Eigen::Vector3d(x, 0.0, 0.0); };
    const auto closed = [&](const GicpCycle& c, const Eigen::Matrix3d& R, double x) {
        return c.Closed(R, at(x), 1e-4, 1e-5, 0.005, 5e-4);
    };
    for (int k = 2; k <= GicpCycle::kLongest; ++k) {
        GicpCycle mm, cm;  // iterates 0, 1, ..., k-1 mm (cm) along x, then back at 0
        for (int j = 0; j < k; ++j) {
            mm.Left(I, at(1e-3 * j));
            cm.Left(I, at(1e-2 * j));
        }
        EXPECT_EQ(closed(mm, I, 0.0), std::optional<bool>(true)) << "cycle of " << k;
        EXPECT_EQ(closed(cm, I, 0.0), std::optional<bool>(false)) << "cycle of " << k;
        EXPECT_FALSE(closed(mm, I, 5e-4).has_value()) << "not back: " << k;
        EXPECT_FALSE(closed(mm, turn, 0.0).has_value()) << "turned away: " << k;
    }
    GicpCycle crawl, longer;
    for (int j = 0; j < 10; ++j) crawl.Left(I, at(1e-3 * j));
    EXPECT_FALSE(closed(crawl, I, 1e-2).has_value());
    for (int j = 0; j < GicpCycle::kLongest + 1; ++j) longer.Left(I, at(1e-3 * j));
    EXPECT_FALSE(closed(longer, I, 0.0).has_value());  // 5 sets: beyond the iterates kept
    GicpCycle still;  // one step that did not move: the plain stop rule's case, not a cycle
    still.Left(I, at(0.0));
    EXPECT_FALSE(closed(still, I, 0.0).has_value());
    // Tight in translation, one iterate of the cycle turned by 1e-3 rad: not converged.
    GicpCycle turned;
    turned.Left(I, at(0.0));
    turned.Left(Eigen::AngleAxisd(1e-3, Eigen::Vector3d::UnitZ()).toRotationMatrix(), at(1e-3));
    EXPECT_EQ(closed(turned, I, 0.0), std::optional<bool>(false));
}

// The planes the quality test's point-to-plane Hessian uses: on a tilted plane every point's
// normal is the plane's, far from the origin too (float coordinates at 500 m).
TEST(Registration, LocalPlaneNormalsAreThePlanesNormalFarFromTheOrigin) {
    const Eigen::Vector3d n = Eigen::Vector3d(-0.5, 0.2, 1.0).normalized();
    for (const float offset : {0.0f, 500.0f}) {
        PointCloud plane;
        for (int i = 0; i < 30; ++i) {
            for (int j = 0; j < 30; ++j) {
                const float x = 0.3f * static_cast<float>(i), y = 0.3f * static_cast<float>(j);
                plane.emplace_back(offset + x, offset + y, 0.5f * x - 0.2f * y);
            }
        }
        const PointKdTree tree(plane);
        const std::vector<Eigen::Vector3d> normals = LocalPlaneNormals(plane, tree, 20);
        ASSERT_EQ(normals.size(), plane.size());
        for (const Eigen::Vector3d& m : normals) {
            EXPECT_NEAR(std::abs(m.dot(n)), 1.0, 1e-6) << "offset " << offset;
        }
    }
}

TEST(Registration, ConfigValidationNamesTheField) {
    const auto message = [](const RegistrationConfig& config) {
        try {
            config.Validate();
        } catch (const std::invalid_argument& e) {
            return std::string(e.what());
        }
        return std::string();
    };
    EXPECT_EQ(message(RegistrationConfig{}), "");
    RegistrationConfig config;
    config.converged_translation_m = 0;
    EXPECT_NE(message(config).find("converged_translation_m"), std::string::npos);
    config = RegistrationConfig{};
    config.converged_rotation = -1e-5;
    EXPECT_NE(message(config).find("converged_rotation"), std::string::npos);
    config = RegistrationConfig{};
    config.covariance_neighbours = 3;
    EXPECT_NE(message(config).find("covariance_neighbours"), std::string::npos);
}

TEST(Downsample, VoxelCountMatchesReadmeWithinFewPercent) {
    const PointCloud scan = Load("mulran_kaist03_keyframes/Scans/000000.pcd");
    const PointCloud down = VoxelDownsample(scan, 0.2);
    EXPECT_NEAR(static_cast<double>(down.size()), 23837.0, 0.03 * 23837.0);  // README's count
}

// The flat hash table (open addressing) against the definition: voxels in the order first seen,
// each the mean of its finite points (several per voxel, negative coordinates), a NaN skipped.
TEST(Downsample, CentroidsInFirstSeenOrderMatchTheDefinition) {
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> u(-3.0F, 3.0F);
    PointCloud cloud;
    for (int i = 0; i < 20000; ++i) cloud.emplace_back(u(rng), u(rng), 0.1F * u(rng));
    cloud.emplace_back(std::nanf(""), 0.0F, 0.0F);
    const double inv = 1.0 / 0.2;  // as VoxelDownsample computes the voxel
    std::vector<std::array<std::int64_t, 3>> order;
    std::map<std::array<std::int64_t, 3>, std::pair<Eigen::Vector3d, int>> voxels;
    for (const Eigen::Vector3f& p : cloud) {
        if (!p.allFinite()) continue;
        const std::array<std::int64_t, 3> v{static_cast<std::int64_t>(std::floor(p.x() * inv)),
                                            static_cast<std::int64_t>(std::floor(p.y() * inv)),
                                            static_cast<std::int64_t>(std::floor(p.z() * inv))};
        auto [it, inserted] = voxels.try_emplace(v, Eigen::Vector3d::Zero(), 0);
        if (inserted) order.push_back(v);
        it->second.first += p.cast<double>();
        ++it->second.second;
    }
    const PointCloud down = VoxelDownsample(cloud, 0.2);
    ASSERT_EQ(down.size(), order.size());
    ASSERT_GT(cloud.size(), 2 * order.size());  // several points per voxel
    for (std::size_t k = 0; k < order.size(); ++k) {
        const auto& [sum, n] = voxels.at(order[k]);
        EXPECT_EQ(down[k], Eigen::Vector3f((sum / n).cast<float>())) << "voxel " << k;
    }
}

// One point at the centre of each of 2^15 voxels fills the table to its largest load (1/2), so
// probes run long and wrap past its end: every point comes back as its voxel, in order.
TEST(Downsample, TableAtHalfLoadKeepsEveryVoxel) {
    PointCloud cloud;
    for (int x = -16; x < 16; ++x) {
        for (int y = -16; y < 16; ++y) {
            for (int z = -16; z < 16; ++z) cloud.emplace_back(0.5F * x + 0.25F, 0.5F * y, 0.5F * z);
        }
    }
    for (Eigen::Vector3f& p : cloud) p += Eigen::Vector3f(0.0F, 0.25F, 0.25F);
    ASSERT_EQ(cloud.size(), std::size_t{1} << 15);
    const PointCloud down = VoxelDownsample(cloud, 0.5);
    ASSERT_EQ(down.size(), cloud.size());
    for (std::size_t k = 0; k < cloud.size(); ++k) EXPECT_EQ(down[k], cloud[k]) << "point " << k;
}

}  // namespace
}  // namespace certislam::slam
