// The real loop stage on a simulated two-robot mission: every accepted loop closure agrees
// with the simulator's ground truth (precision 1.0), and both robots' loops are found.
#include "slam/frontend/loop_verification.h"

#include <gtest/gtest.h>

#include <chrono>
#include <iostream>
#include <numbers>

#include "slam/sim/simulator.h"

namespace certislam::slam {
namespace {

constexpr double kTrueLoopMaxTranslationM = 0.5;  // a correct registration is within this
constexpr double kTrueLoopMaxRotationDeg = 2.0;
constexpr int kMinInterRobotLoops = 3;

struct LoopError {
    double translation_m;
    double rotation_deg;
};

LoopError ErrorAgainstTruth(const LoopClosure& loop, const SimulatedMission& mission) {
    const auto& truth = mission.T_world_sensor_truth;
    const Eigen::Isometry3d T_true =
        truth[loop.a.robot][loop.a.index].inverse() * truth[loop.b.robot][loop.b.index];
    const Eigen::Isometry3d E = T_true.inverse() * loop.T_a_b;
    return {E.translation().norm(),
            Eigen::AngleAxisd(E.rotation()).angle() * 180.0 / std::numbers::pi};
}

TEST(MissionVerify, SimulatedMissionLoopsAreRealDetectionsWithPrecisionOne) {
    ASSERT_TRUE(FrontEndVerificationAvailable());
    const SimulatedMission mission = SimulateMission(SimulatorConfig{});
    LoopDetectionConfig config;
    const auto start = std::chrono::steady_clock::now();
    const LoopDetectionResult result = DetectLoops(mission.robots, {}, config);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    EXPECT_TRUE(result.warnings.empty());
    int wrong = 0;
    for (const auto& loop : result.loops) {
        EXPECT_FALSE(loop.from_ground_truth);
        const LoopError e = ErrorAgainstTruth(loop, mission);
        const bool ok =
            e.translation_m < kTrueLoopMaxTranslationM && e.rotation_deg < kTrueLoopMaxRotationDeg;
        wrong += !ok;
        EXPECT_TRUE(ok) << loop.a.robot << ":" << loop.a.index << " -> " << loop.b.robot << ":"
                        << loop.b.index << " off by " << e.translation_m << " m, " << e.rotation_deg
                        << " deg";
        EXPECT_GT(loop.kappa, 0.0);
        EXPECT_GT(loop.tau, 0.0);
    }
    const auto& s = result.stats;
    EXPECT_GE(s.inter_robot, kMinInterRobotLoops);
    EXPECT_EQ(s.verified, s.candidates - s.rejected_registration);
    EXPECT_EQ(static_cast<int>(result.loops.size()), s.verified - s.rejected_outliers);
    EXPECT_GT(s.cloud_bytes_sent, 0);
    // Bandwidth: descriptors to every peer + downsampled clouds of inter-robot candidates, per
    // keyframe, against sending every keyframe's downsampled cloud.
    const double sent_per_keyframe =
        static_cast<double>(s.descriptor_bytes_sent + s.cloud_bytes_sent) / s.descriptors;
    std::cout << "bytes per keyframe: descriptors " << s.descriptor_bytes_sent / s.descriptors
              << ", clouds " << s.cloud_bytes_sent / s.descriptors << ", total "
              << sent_per_keyframe << "\n";
    std::cout << "keyframes " << s.descriptors << ", candidates " << s.candidates
              << ", registration rejected " << s.rejected_registration << ", PCM rejected "
              << s.rejected_outliers << ", loops " << result.loops.size() << " (inter "
              << s.inter_robot << ", intra " << s.intra_robot << "), wrong " << wrong << ", "
              << seconds << " s\n";
}

}  // namespace
}  // namespace certislam::slam
