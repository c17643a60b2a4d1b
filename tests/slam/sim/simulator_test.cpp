// The mission simulator: determinism, drift character, revisits, the tunnel, scan size.
#include "slam/sim/simulator.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <stdexcept>

namespace certislam::slam {
namespace {

constexpr double kRevisitM = 4.0;              // "a few metres": Scan Context finds these
constexpr double kStepTranslationErrM = 0.05;  // per keyframe (3 m) odometry error bound
constexpr double kStepRotationErrRad = 0.2 * M_PI / 180.0;
constexpr double kWallTolM = 0.15;  // range noise 2 cm: points within this of a wall

double Yaw(const Eigen::Matrix3d& R) { return std::atan2(R(1, 0), R(0, 0)); }

// Odometry pose error of keyframe k: truth vs odometry mapped into the world by T_world_odom.
Eigen::Isometry3d PoseError(const MissionGenerator& g, int r, int k) {
    return (g.T_world_odom(r) * g.PoseOnly(r, k).T_odom_sensor).inverse() *
           g.T_world_sensor_truth(r, k);
}

TEST(Simulator, DefaultMissionHasAFewHundredKeyframesAndOdometryStartsAtIdentity) {
    const MissionGenerator g(SimulatorConfig{});
    ASSERT_EQ(g.num_robots(), 2);
    const int total = g.num_keyframes(0) + g.num_keyframes(1);
    EXPECT_GE(total, 200);
    EXPECT_LE(total, 600);
    for (int r = 0; r < 2; ++r) {
        EXPECT_TRUE(g.PoseOnly(r, 0).T_odom_sensor.isApprox(Eigen::Isometry3d::Identity()));
        EXPECT_EQ(g.PoseOnly(r, 3).index, 3);
        EXPECT_EQ(g.PoseOnly(r, 3).robot, r);
        EXPECT_GT(g.PoseOnly(r, 3).stamp_ns, g.PoseOnly(r, 2).stamp_ns);
    }
    // The two robots do not start at the same place: their odometry frames differ.
    EXPECT_GT((g.T_world_odom(0).translation() - g.T_world_odom(1).translation()).norm(), 10.0);
}

TEST(Simulator, SameSeedSameMissionDifferentSeedDifferentMission) {
    SimulatorConfig cfg;
    const MissionGenerator a(cfg), b(cfg);
    cfg.seed = 2;
    const MissionGenerator c(cfg);
    for (int r = 0; r < 2; ++r) {
        const int k = a.num_keyframes(r) - 1;
        EXPECT_TRUE(a.PoseOnly(r, k).T_odom_sensor.isApprox(b.PoseOnly(r, k).T_odom_sensor, 0));
        EXPECT_FALSE(a.PoseOnly(r, k).T_odom_sensor.isApprox(c.PoseOnly(r, k).T_odom_sensor));
        const auto ka = a.Generate(r, 5), kb = b.Generate(r, 5), kc = c.Generate(r, 5);
        ASSERT_EQ(ka.keyframe.cloud->size(), kb.keyframe.cloud->size());
        for (size_t i = 0; i < ka.keyframe.cloud->size(); ++i) {
            ASSERT_EQ((*ka.keyframe.cloud)[i], (*kb.keyframe.cloud)[i]);
        }
        const bool same_size = ka.keyframe.cloud->size() == kc.keyframe.cloud->size();
        EXPECT_FALSE(same_size && *ka.keyframe.cloud == *kc.keyframe.cloud);
    }
}

TEST(Simulator, OdometryDriftsSlowlyInYawAndHeightWithSmallStepErrors) {
    double early_yaw = 0, late_yaw = 0, late_z = 0;
    for (std::uint64_t seed = 1; seed <= 8; ++seed) {
        SimulatorConfig cfg;
        cfg.seed = seed;
        const MissionGenerator g(cfg);
        for (int r = 0; r < 2; ++r) {
            const int n = g.num_keyframes(r);
            for (int k = 0; k + 1 < n; ++k) {
                // Consecutive relative-pose errors are small (drift, not white noise).
                const Eigen::Isometry3d odo =
                    g.PoseOnly(r, k).T_odom_sensor.inverse() * g.PoseOnly(r, k + 1).T_odom_sensor;
                const Eigen::Isometry3d tru =
                    g.T_world_sensor_truth(r, k).inverse() * g.T_world_sensor_truth(r, k + 1);
                const Eigen::Isometry3d e = odo.inverse() * tru;
                ASSERT_LT(e.translation().norm(), kStepTranslationErrM) << r << " " << k;
                ASSERT_LT(Eigen::AngleAxisd(e.linear()).angle(), kStepRotationErrRad);
            }
            early_yaw += std::abs(Yaw(PoseError(g, r, n / 10).linear()));
            late_yaw += std::abs(Yaw(PoseError(g, r, n - 1).linear()));
            late_z += std::abs(PoseError(g, r, n - 1).translation().z());
        }
    }
    // Averaged over 16 trajectories: yaw error grows along the way, height drifts.
    EXPECT_GT(late_yaw, 3.0 * early_yaw);
    EXPECT_GT(late_yaw / 16, 0.3 * M_PI / 180.0);
    EXPECT_LT(late_yaw / 16, 10.0 * M_PI / 180.0);
    EXPECT_GT(late_z / 16, 0.1);
}

double Nearest(const MissionGenerator& g, int r, const Eigen::Vector3d& p, int k_begin, int k_end) {
    double best = 1e9;
    for (int k = k_begin; k < k_end; ++k) {
        best = std::min(best, (g.T_world_sensor_truth(r, k).translation() - p).norm());
    }
    return best;
}

TEST(Simulator, RevisitsComeWithinAFewMetres) {
    const MissionGenerator g(SimulatorConfig{});
    // Robot 0 closes its loop: its first keyframe is revisited much later.
    const int n0 = g.num_keyframes(0);
    EXPECT_LT(Nearest(g, 0, g.T_world_sensor_truth(0, 0).translation(), 50, n0), kRevisitM);
    // Inter-robot encounters: many robot 1 keyframes lie near robot 0's.
    int near = 0;
    for (int k = 0; k < g.num_keyframes(1); ++k) {
        if (Nearest(g, 0, g.T_world_sensor_truth(1, k).translation(), 0, n0) < kRevisitM) ++near;
    }
    EXPECT_GT(near, 30);
}

TEST(Simulator, RobotsDriveOnStreetsClearOfBuildingsAndTrees) {
    const MissionGenerator g(SimulatorConfig{});
    constexpr double kClearanceM = 1.0;
    for (int r = 0; r < g.num_robots(); ++r) {
        for (int k = 0; k < g.num_keyframes(r); ++k) {
            const Eigen::Vector3d p = g.T_world_sensor_truth(r, k).translation();
            for (const SimBox& b : g.world().boxes()) {
                const Eigen::Vector3d lo = b.min.array() - kClearanceM;
                const Eigen::Vector3d hi = b.max.array() + kClearanceM;
                const bool inside =
                    (p.array() > lo.array()).all() && (p.array() < hi.array()).all();
                ASSERT_FALSE(inside) << "robot " << r << " keyframe " << k;
            }
            for (const SimCylinder& c : g.world().cylinders()) {
                ASSERT_GT((p.head<2>() - c.center).norm(), c.radius + kClearanceM);
            }
        }
    }
}

TEST(Simulator, TunnelStretchHasPointsOnBothWalls) {
    const MissionGenerator g(SimulatorConfig{});
    const SimStreets& st = g.streets();
    const double mid = 0.5 * (st.tunnel_x_begin + st.tunnel_x_end);
    int best_k = -1;
    for (int k = 0; k < g.num_keyframes(1); ++k) {
        const Eigen::Vector3d p = g.T_world_sensor_truth(1, k).translation();
        if (std::abs(p.y()) < 5.0 && std::abs(p.x() - mid) < 2.0) best_k = k;
    }
    ASSERT_GE(best_k, 0) << "robot 1 does not pass the tunnel";
    const SimulatedKeyframe kf = g.Generate(1, best_k);
    int left = 0, right = 0, roof = 0;
    for (const Eigen::Vector3f& q : *kf.keyframe.cloud) {
        const Eigen::Vector3d w = kf.T_world_sensor_truth * q.cast<double>();
        if (std::abs(w.y() - st.tunnel_half_width) < kWallTolM) ++left;
        if (std::abs(w.y() + st.tunnel_half_width) < kWallTolM) ++right;
        if (std::abs(w.z() - g.config().world.tunnel_height_m) < kWallTolM) ++roof;
    }
    EXPECT_GT(left, 1000);
    EXPECT_GT(right, 1000);
    EXPECT_GT(roof, 1000);
}

TEST(Simulator, ScansHaveTensOfThousandsOfPointsAndAreFast) {
    const MissionGenerator g(SimulatorConfig{});
    const auto t0 = std::chrono::steady_clock::now();
    size_t points = 0;
    constexpr int kScans = 20;
    for (int k = 0; k < kScans; ++k) {
        const auto kf = g.Generate(0, 5 * k);
        EXPECT_GT(kf.keyframe.cloud->size(), 15000u);
        EXPECT_LT(kf.keyframe.cloud->size(), 40000u);
        points += kf.keyframe.cloud->size();
    }
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    std::printf("simulator: %.0f points/scan, %.1f ms/scan\n", double(points) / kScans,
                ms / kScans);
    EXPECT_LT(ms / kScans, 100.0);  // generous: debug builds and a loaded 2-core machine
}

TEST(Simulator, SixtyFourRingOusterLikeSensor) {
    SimulatorConfig cfg;
    cfg.lidar = SimLidarConfig::Ouster64();
    const MissionGenerator g(cfg);
    const auto kf = g.Generate(0, 10);
    float max_el = -1, min_el = 1;
    for (const auto& p : *kf.keyframe.cloud) {
        const float el = std::atan2(p.z(), p.head<2>().norm());
        max_el = std::max(max_el, el);
        min_el = std::min(min_el, el);
    }
    EXPECT_NEAR(min_el, -22.5 * M_PI / 180.0, 0.01);
    EXPECT_GT(max_el, 10.0 * M_PI / 180.0);
}

TEST(Simulator, ValidateNamesTheField) {
    SimulatorConfig cfg;
    cfg.lidar.rings = 0;
    EXPECT_THROW(MissionGenerator{cfg}, std::invalid_argument);
    try {
        cfg.Validate();
        ADD_FAILURE() << "no exception";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("rings"), std::string::npos) << e.what();
    }
}

}  // namespace
}  // namespace certislam::slam
