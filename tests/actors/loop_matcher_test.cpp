// The loop matcher's outlier rejection: incremental PCM keeps true loops and drops false ones
// (also a false clique that came first: it is withdrawn when the true one outgrows it); over
// real inproc sockets, aliased keyframes (a robot's cloud copied from another place) make false
// loops that never reach the solvers' graphs; a withdrawal sent to a solver removes the loop
// and a stale re-broadcast does not bring it back.
#include <gtest/gtest.h>

#include <memory>
#include <set>
#include <thread>

#include "actors/convert.h"
#include "actors/descriptor_actor.h"
#include "actors/ingest_actor.h"
#include "actors/loop_matcher_actor.h"
#include "actors/loop_matcher_actor_pcm.h"
#include "actors/solver_actor.h"
#include "certislam/v1/control.pb.h"
#include "slam/sim/simulator.h"
#include "solver_fixture.h"

namespace certislam::actors {
namespace {

constexpr int kPoses = 60;
constexpr double kLoopSigmaT_m = 0.05;
constexpr double kLoopSigmaR_rad = 0.01;
constexpr double kFalseLoopMinError_m = 3.0;  // an aliased keyframe is this far from the truth
constexpr auto kTimeout = std::chrono::seconds(60);

slam::Information6 LoopInformation() {
    slam::Information6 info = slam::Information6::Zero();
    info.diagonal() << Eigen::Vector3d::Constant(1.0 / (kLoopSigmaT_m * kLoopSigmaT_m)),
        Eigen::Vector3d::Constant(1.0 / (kLoopSigmaR_rad * kLoopSigmaR_rad));
    return info;
}

IncrementalPcm WithOdometry(const TwoRobotProblem& p) {
    IncrementalPcm pcm(slam::PcmConfig{});
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

std::set<std::pair<slam::PoseId, slam::PoseId>> Ends(const std::vector<slam::LoopClosure>& ls) {
    std::set<std::pair<slam::PoseId, slam::PoseId>> out;
    for (const auto& l : ls) out.insert({l.a, l.b});
    return out;
}

TEST(IncrementalPcm, KeepsTrueLoopsAndDropsFalseOnes) {
    const TwoRobotProblem p = MakeTwoRobotProblem(kPoses, 6, 3);
    IncrementalPcm pcm = WithOdometry(p);
    std::vector<slam::LoopClosure> all = p.loops;
    for (int k = 0; k < 3; ++k) {  // false: a true loop moved 5 m and turned 30 degrees
        slam::LoopClosure wrong = p.loops[static_cast<size_t>(k)];
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
    const TwoRobotProblem p = MakeTwoRobotProblem(kPoses, 5, 5);  // 5 distinct loops
    IncrementalPcm pcm = WithOdometry(p);
    // Two false loops consistent with each other (the second follows the first by odometry).
    slam::LoopClosure f1;
    f1.a = {0, 5};
    f1.b = {1, 40};
    f1.T_a_b = Pose(0.3, 4.0, 1.0, 0.0);
    slam::LoopClosure f2 = f1;
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
    const TwoRobotProblem p = MakeTwoRobotProblem(kPoses, 0, 7);
    IncrementalPcm pcm = WithOdometry(p);
    slam::LoopClosure wrong;
    wrong.a = {0, 2};
    wrong.b = {0, 50};
    wrong.T_a_b = Eigen::Isometry3d::Identity();  // the odometry says tens of metres apart
    ASSERT_TRUE(pcm.Add(wrong, LoopInformation()));
    EXPECT_EQ(pcm.RejectedByOdometry(), 1);
    slam::LoopClosure unknown = wrong;
    unknown.a = {2, 0};  // no odometry for robot 2: refused
    EXPECT_FALSE(pcm.Add(unknown, LoopInformation()));
}

TEST(LoopWithdrawal, RoundTripsAndIsNotALoop) {
    const auto w = LoopWithdrawal({0, 3}, {1, 9});
    const auto ends = WithdrawnEnds(w);
    ASSERT_TRUE(ends.has_value());
    EXPECT_EQ(ends->first, (slam::PoseId{0, 3}));
    EXPECT_EQ(ends->second, (slam::PoseId{1, 9}));
    EXPECT_FALSE(FromProto(w).has_value());  // old receivers drop it as malformed
    slam::LoopClosure loop;
    loop.a = {0, 3};
    loop.b = {1, 9};
    EXPECT_FALSE(WithdrawnEnds(ToProto(loop)).has_value());
}

}  // namespace
}  // namespace certislam::actors
