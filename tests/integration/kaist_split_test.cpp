// The mission pipeline on real LiDAR data: the MulRan KAIST03 keyframes split into two robots
// (even keyframes = robot 0, odd keyframes = robot 1 with every odometry pose moved by an unknown
// rigid offset). The real front end (Scan Context + GICP + PCM) must find inter-robot loops, the
// certified solution must be certified, and robot 1's certified trajectory must recover the
// offset: T_odom0_odom1 = T_offset^-1 within 0.2 m and 1 degree.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

#include "certify/pipeline/mission.h"
#include "slam/core/keyframe.h"
#include "slam/io/keyframe_sources_io.h"
#include "tests/data_paths.h"

namespace certislam::certify {
namespace {

const std::string kKaist = test_data::DataPath("lidar/mulran_kaist03_keyframes");
constexpr double kOffsetToleranceM = 0.2;    ///< recovered offset translation error
constexpr double kOffsetToleranceDeg = 1.0;  ///< recovered offset rotation error
constexpr double kOffsetYawDeg = 40.0;       ///< the unknown offset's yaw
constexpr double kRadToDeg = 180.0 / M_PI;   ///< radians to degrees
constexpr int kMinKeyframesPerRobot = 8;     ///< the folder has 21 keyframes: 11 + 10

/// The rigid offset applied to robot 1's odometry: T_odom1_world (robot 1's odometry frame is
/// the world frame moved by it; robot 0's odometry frame is the world frame).
Eigen::Isometry3d OffsetOdom1World() {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::AngleAxisd(kOffsetYawDeg / kRadToDeg, Eigen::Vector3d::UnitZ()).matrix();
    T.translation() = Eigen::Vector3d(25.0, -12.0, 1.5);
    return T;
}

double RotationErrorDeg(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
    return Eigen::AngleAxisd(a.linear().transpose() * b.linear()).angle() * kRadToDeg;
}

/// Robot 0 = even keyframes as read, robot 1 = odd keyframes with T_odom_sensor premultiplied by
/// the offset; indices renumbered from 0 per robot, clouds shared.
std::vector<std::vector<slam::Keyframe>> SplitIntoTwoRobots(
    const std::vector<slam::Keyframe>& keyframes, const Eigen::Isometry3d& T_odom1_world) {
    std::vector<std::vector<slam::Keyframe>> robots(2);
    for (size_t k = 0; k < keyframes.size(); ++k) {
        const int r = static_cast<int>(k % 2);
        slam::Keyframe kf = keyframes[k];
        kf.robot = r;
        kf.index = static_cast<int>(robots[r].size());
        if (r == 1) kf.T_odom_sensor = T_odom1_world * kf.T_odom_sensor;
        robots[r].push_back(kf);
    }
    return robots;
}

class KaistSplit : public ::testing::Test {
  protected:
    static void SetUpTestSuite() {
        error_ = new std::string;
        const auto read = slam::ReadScLioSamFolder(kKaist);
        ASSERT_TRUE(read.ok()) << read.error;
        robots_ = new std::vector<std::vector<slam::Keyframe>>(
            SplitIntoTwoRobots(read.keyframes, OffsetOdom1World()));
        MissionConfig config;
        config.loops.source = slam::LoopSource::kFrontEnd;
        try {
            result_ = new MissionResult(RunMission(*robots_, {}, config));
        } catch (const std::runtime_error& e) {
            *error_ = e.what();  // e.g. no inter-robot loop: the joint graph is disconnected
        }
    }
    static void TearDownTestSuite() {
        delete result_;
        delete robots_;
        delete error_;
        error_ = nullptr;
        result_ = nullptr;
        robots_ = nullptr;
    }
    void SetUp() override { ASSERT_NE(result_, nullptr) << "the mission did not run: " << *error_; }

    static std::vector<std::vector<slam::Keyframe>>* robots_;
    static MissionResult* result_;
    static std::string* error_;
};
std::vector<std::vector<slam::Keyframe>>* KaistSplit::robots_ = nullptr;
MissionResult* KaistSplit::result_ = nullptr;
std::string* KaistSplit::error_ = nullptr;

TEST_F(KaistSplit, FrontEndFindsInterRobotLoops) {
    ASSERT_GE(static_cast<int>((*robots_)[1].size()), kMinKeyframesPerRobot);
    EXPECT_TRUE(result_->warnings.empty()) << result_->warnings.front();
    EXPECT_GE(result_->loop_stats.inter_robot, 1);
    for (const auto& loop : result_->loops) EXPECT_FALSE(loop.from_ground_truth);
}

TEST_F(KaistSplit, SolutionIsCertified) {
    EXPECT_EQ(result_->status, MissionResult::Status::kOk);
    EXPECT_EQ(result_->solution.certificate.status, CertificateResult::Status::kCertified);
}

TEST_F(KaistSplit, CertifiedTrajectoryRecoversTheOffset) {
    const auto& certified = result_->certified;
    ASSERT_EQ(certified.size(), 2u);
    ASSERT_EQ(certified[1].size(), (*robots_)[1].size());
    // The solution's frame -> robot 0's odometry frame, through robot 0's first keyframe (the
    // solution is anchored there; this holds whichever frame the solution is expressed in).
    const Eigen::Isometry3d T_odom0_sol =
        (*robots_)[0][0].T_odom_sensor * certified[0][0].T_world_body.inverse();
    const Eigen::Isometry3d T_odom0_odom1_true = OffsetOdom1World().inverse();
    double max_t = 0.0;
    double max_r = 0.0;
    for (size_t i = 0; i < certified[1].size(); ++i) {
        // Each of robot 1's certified poses gives one estimate of T_odom0_odom1.
        const Eigen::Isometry3d T_odom0_odom1 =
            T_odom0_sol * certified[1][i].T_world_body * (*robots_)[1][i].T_odom_sensor.inverse();
        const double dt = (T_odom0_odom1.translation() - T_odom0_odom1_true.translation()).norm();
        const double dr = RotationErrorDeg(T_odom0_odom1, T_odom0_odom1_true);
        max_t = std::max(max_t, dt);
        max_r = std::max(max_r, dr);
        EXPECT_LT(dt, kOffsetToleranceM) << "robot 1 keyframe " << i;
        EXPECT_LT(dr, kOffsetToleranceDeg) << "robot 1 keyframe " << i;
    }
    RecordProperty("offset_error_max_m", std::to_string(max_t));
    RecordProperty("offset_error_max_deg", std::to_string(max_r));
    std::printf(
        "offset error (max over robot 1's keyframes): %.4f m, %.4f deg; loops: %d "
        "inter-robot of %d candidates; front end %.2f s, back end %.2f s\n",
        max_t, max_r, result_->loop_stats.inter_robot, result_->loop_stats.candidates,
        result_->front_end_seconds, result_->back_end_seconds);
}

}  // namespace
}  // namespace certislam::certify
