// Incremental PCM keeps true loops and drops false ones (also a false clique that came first:
// it is withdrawn when the true one outgrows it); intra-robot loops must agree with odometry.
#include "slam/frontend/incremental_pcm.h"

#include <gtest/gtest.h>

#include <set>
#include <utility>
#include <vector>

#include "tests/slam/frontend/two_robot_circles.h"

namespace certislam::slam {
namespace {

using testing::Pose;
using testing::TwoRobotCircles;

constexpr int kPoses = 60;
constexpr double kLoopSigmaT_m = 0.05;
constexpr double kLoopSigmaR_rad = 0.01;

TwoRobotCircles MakeTwoRobotProblem(int n, int loops, unsigned seed) {
    return testing::MakeTwoRobotCircles(n, loops, seed, 1.0, 1.0);  // PCM reads no weights
}

Information6 LoopInformation() {
    Information6 info = Information6::Zero();
    info.diagonal() << Eigen::Vector3d::Constant(1.0 / (kLoopSigmaT_m * kLoopSigmaT_m)),
        Eigen::Vector3d::Constant(1.0 / (kLoopSigmaR_rad * kLoopSigmaR_rad));
    return info;
}

IncrementalPcm WithOdometry(const TwoRobotCircles& p) {
    IncrementalPcm pcm(PcmConfig{});
    for (int r = 0; r < 2; ++r) {
        double travelled = 0.0;
        for (int k = 0; k < kPoses; ++k) {
            const auto& odom = p.odometry[static_cast<size_t>(r)];
            if (k > 0) travelled += (odom[k].translation() - odom[k - 1].translation()).norm();
            pcm.SetOdometry({r, k}, {odom[static_cast<size_t>(k)], travelled});
        }
    }
    return pcm;
}

std::set<std::pair<PoseId, PoseId>> Ends(const std::vector<LoopClosure>& ls) {
    std::set<std::pair<PoseId, PoseId>> out;
    for (const auto& l : ls) out.insert({l.a, l.b});
    return out;
}

TEST(IncrementalPcm, KeepsTrueLoopsAndDropsFalseOnes) {
    const TwoRobotCircles p = MakeTwoRobotProblem(kPoses, 6, 3);
    IncrementalPcm pcm = WithOdometry(p);
    std::vector<LoopClosure> all = p.loops;
    for (int k = 0; k < 3; ++k) {  // false: a true loop moved 5 m and turned 30 degrees
        LoopClosure wrong = p.loops[static_cast<size_t>(k)];
        wrong.b.index = (wrong.b.index + 7 + 5 * k) % kPoses;
        wrong.T_a_b = wrong.T_a_b * Pose(0.5, 5.0, -2.0 * k, 0.0);
        all.push_back(wrong);
    }
    for (const auto& l : all) ASSERT_TRUE(pcm.Add(l, LoopInformation()));
    EXPECT_FALSE(pcm.Add(all.front(), LoopInformation()));  // same ends twice
    EXPECT_EQ(Ends(pcm.Consistent()), Ends(p.loops));
    EXPECT_TRUE(pcm.Exact());
}

TEST(IncrementalPcm, EarlierFalseCliqueIsReplacedByTheLargerTrueOne) {
    const TwoRobotCircles p = MakeTwoRobotProblem(kPoses, 5, 5);  // 5 distinct loops
    IncrementalPcm pcm = WithOdometry(p);
    // Two false loops consistent with each other (the second follows the first by odometry).
    LoopClosure f1;
    f1.a = {0, 5};
    f1.b = {1, 40};
    f1.T_a_b = Pose(0.3, 4.0, 1.0, 0.0);
    LoopClosure f2 = f1;
    f2.a = {0, 6};
    f2.b = {1, 41};
    f2.T_a_b = p.odometry[0][5].inverse() * p.odometry[0][6];
    f2.T_a_b = f2.T_a_b.inverse() * f1.T_a_b * (p.odometry[1][40].inverse() * p.odometry[1][41]);
    ASSERT_TRUE(pcm.Add(f1, LoopInformation()));
    EXPECT_TRUE(pcm.Consistent().empty());  // one loop alone is below min_clique_size
    ASSERT_TRUE(pcm.Add(f2, LoopInformation()));
    EXPECT_EQ(Ends(pcm.Consistent()), Ends({f1, f2}));  // not yet distinguishable
    for (const auto& l : p.loops) ASSERT_TRUE(pcm.Add(l, LoopInformation()));
    EXPECT_EQ(Ends(pcm.Consistent()), Ends(p.loops));  // the false pair dropped out
}

TEST(IncrementalPcm, IntraRobotLoopMustAgreeWithOdometry) {
    const TwoRobotCircles p = MakeTwoRobotProblem(kPoses, 0, 7);
    IncrementalPcm pcm = WithOdometry(p);
    LoopClosure wrong;
    wrong.a = {0, 2};
    wrong.b = {0, 50};
    wrong.T_a_b = Eigen::Isometry3d::Identity();  // the odometry says tens of metres apart
    ASSERT_TRUE(pcm.Add(wrong, LoopInformation()));
    EXPECT_EQ(pcm.RejectedByOdometry(), 1);
    LoopClosure unknown = wrong;
    unknown.a = {2, 0};  // no odometry for robot 2: refused
    EXPECT_FALSE(pcm.Add(unknown, LoopInformation()));
}

}  // namespace
}  // namespace certislam::slam
