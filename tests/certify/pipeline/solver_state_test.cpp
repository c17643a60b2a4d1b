// SolverState: robots exchanging only public poses reach the centralised certified optimum
// (SolveCertifiedJoint on the same joint graph), in any update order, and a silent
// robot does not stop the others.
#include "certify/pipeline/solver_state.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>

#include "tests/certify/pipeline/two_robot_problem.h"

namespace certislam::certify {
namespace {

constexpr double kPoseTolerance = 1e-5;  ///< metres / radians-ish (matrix entries)
constexpr int kMaxRounds = 3000;

/// Runs rounds of Step + exchange until every robot is locally converged for 3 rounds in a row.
/// `order` picks which robots step in a round (the asynchronous schedule).
int RunUntilConverged(std::vector<SolverState>& robots,
                      const std::function<std::vector<int>(int round)>& order) {
    int quiet = 0;
    for (int round = 0; round < kMaxRounds; ++round) {
        double team_cost = 0.0;
        bool all_ok = true;
        for (int k : order(round)) {
            const auto step = robots[k].Step(1.0);
            team_cost += step.cost;
            all_ok = all_ok && step.status == SolverStepResult::Status::kLocalOk;
            for (auto& other : robots) {
                if (other.robot() != k) other.SetNeighbourPoses(robots[k].PublicPoses(round));
            }
        }
        quiet = all_ok ? quiet + 1 : 0;
        if (quiet >= 3) return round;
    }
    return -1;
}

TEST(SolverState, TwoRobotsReachTheCentralCertifiedOptimum) {
    const TwoRobotProblem problem = MakeTwoRobotProblem(40, 6, 3);
    std::vector<SolverState> robots;
    for (int k = 0; k < 2; ++k) robots.emplace_back(k, problem.config);
    FeedProblem(problem, robots);
    const int rounds = RunUntilConverged(robots, [](int) { return std::vector<int>{0, 1}; });
    ASSERT_GE(rounds, 0) << "did not converge";
    const auto central = CentralSolution(problem);
    for (int k = 0; k < 2; ++k) {
        int anchor = -1;
        const auto traj = robots[k].Trajectory(0, &anchor);
        EXPECT_EQ(anchor, 0);
        ASSERT_EQ(traj.size(), central[k].size());
        for (size_t i = 0; i < traj.size(); ++i) {
            EXPECT_LT((traj[i].matrix() - central[k][i].matrix()).cwiseAbs().maxCoeff(),
                      kPoseTolerance)
                << "robot " << k << " pose " << i;
        }
    }
}

TEST(SolverState, RandomAsynchronousOrderReachesTheSameOptimum) {
    const TwoRobotProblem problem = MakeTwoRobotProblem(30, 5, 11);
    std::vector<SolverState> robots;
    for (int k = 0; k < 2; ++k) robots.emplace_back(k, problem.config);
    FeedProblem(problem, robots);
    std::mt19937 rng(5);
    // Robot 1 steps three times as often as robot 0, in random bursts.
    const int rounds = RunUntilConverged(robots, [&](int) {
        std::vector<int> order;
        for (int i = 0; i < 4; ++i) order.push_back(rng() % 4 == 0 ? 0 : 1);
        order.push_back(0);
        order.push_back(1);
        return order;
    });
    ASSERT_GE(rounds, 0);
    const auto central = CentralSolution(problem);
    for (int k = 0; k < 2; ++k) {
        const auto traj = robots[k].Trajectory(0, nullptr);
        for (size_t i = 0; i < traj.size(); ++i) {
            EXPECT_LT((traj[i].matrix() - central[k][i].matrix()).cwiseAbs().maxCoeff(),
                      kPoseTolerance);
        }
    }
}

/// Two robots fed `problem` and stepped together until converged (none when they never were).
std::vector<SolverState> ConvergedPair(const TwoRobotProblem& problem) {
    std::vector<SolverState> robots;
    for (int k = 0; k < 2; ++k) robots.emplace_back(k, problem.config);
    FeedProblem(problem, robots);
    if (RunUntilConverged(robots, [](int) { return std::vector<int>{0, 1}; }) < 0) robots.clear();
    return robots;
}

TEST(SolverState, RobotWithoutEncounterKeepsItsOwnFrame) {
    std::vector<SolverState> robots = ConvergedPair(MakeTwoRobotProblem(20, 0, 2));
    ASSERT_EQ(robots.size(), 2u);
    const int team_frame = ComponentAnchor(1, robots[1].InterRobotLoops());
    EXPECT_EQ(team_frame, 1);
    int anchor = -1;
    const auto traj = robots[1].Trajectory(team_frame, &anchor);
    EXPECT_EQ(anchor, 1);
    EXPECT_TRUE(traj[0].isApprox(Eigen::Isometry3d::Identity(), 1e-9));
    EXPECT_TRUE(robots[1].Neighbours().empty());
}

TEST(SolverState, TrajectoryFollowsEveryMoveOfTheBlockAndOfTheAnchor) {
    // Trajectory keeps its last rounding while nothing moved: a moved block and the anchor
    // robot's new pose must each give new poses.
    std::vector<SolverState> robots = ConvergedPair(MakeTwoRobotProblem(20, 2, 2));
    ASSERT_EQ(robots.size(), 2u);
    const auto before = robots[1].Trajectory(0, nullptr);
    EXPECT_EQ(robots[1].Trajectory(0, nullptr).back().matrix(), before.back().matrix());
    Eigen::MatrixXd block = robots[1].FullBlock(0).blocks;
    block.rightCols(1).array() += 0.5;  // the last pose's translation
    robots[1].SetOwnBlock(block);
    const auto moved = robots[1].Trajectory(0, nullptr);
    EXPECT_GT((moved.back().translation() - before.back().translation()).norm(), 0.1);
    PoseBlocks anchor = robots[0].PublicPoses(1);
    const auto zero = std::find(anchor.ids.begin(), anchor.ids.end(), slam::PoseId{0, 0});
    ASSERT_NE(zero, anchor.ids.end());
    anchor.blocks.col(4 * (zero - anchor.ids.begin()) + 3).array() += 1.0;  // robot 0's pose 0
    robots[1].SetNeighbourPoses(anchor);
    const auto reanchored = robots[1].Trajectory(0, nullptr);
    EXPECT_GT((reanchored.back().translation() - moved.back().translation()).norm(), 0.1);
}

TEST(SolverState, KeyframesOutOfOrderAndForeignLoopsAreRefused) {
    SolverConfig config;
    SolverState state(1, config);
    EXPECT_FALSE(state.AddKeyframe(1, Eigen::Isometry3d::Identity()));
    EXPECT_TRUE(state.AddKeyframe(0, Eigen::Isometry3d::Identity()));
    slam::LoopClosure foreign;
    foreign.a = {0, 1};
    foreign.b = {2, 3};
    EXPECT_FALSE(state.AddLoop(foreign));
    slam::LoopClosure mine = foreign;
    mine.b = {1, 0};
    EXPECT_TRUE(state.AddLoop(mine));
    EXPECT_FALSE(state.AddLoop(mine));  // duplicate
    EXPECT_EQ(state.Neighbours(), std::set<int>{0});
    EXPECT_EQ(ComponentAnchor(1, state.InterRobotLoops()), 0);
    slam::LoopClosure far = foreign;
    far.a = {2, 0};
    far.b = {3, 0};
    EXPECT_EQ(ComponentAnchor(3, {far}), 2);
    EXPECT_EQ(ComponentAnchor(3, {}), 3);
}

TEST(SolverState, LoopsReplayedBeforeTheirKeyframesDoNotBreakTheFirstStep) {
    SolverState state(1, SolverConfig{});
    slam::LoopClosure early;
    early.a = {0, 1};
    early.b = {1, 5};  // own keyframe 5 has not arrived yet
    EXPECT_TRUE(state.AddLoop(early));
    ASSERT_TRUE(state.AddKeyframe(0, Eigen::Isometry3d::Identity()));
    EXPECT_EQ(state.Step(1.0).status, SolverStepResult::Status::kLocalOk);
    EXPECT_EQ(state.PublicPoses(0).ids.size(), 1u);  // pose 0 only: the loop is not active
}

}  // namespace
}  // namespace certislam::certify
