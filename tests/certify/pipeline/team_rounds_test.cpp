// Synchronous RBCD++ rounds: robots' SolverStates driven by TeamRounds with every message
// delivered at once reach the published optimum in few rounds, and agree on every decision.
#include "certify/pipeline/team_rounds.h"

#include "certify/pipeline/team_rounds_in_memory.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "slam/core/graph_split.h"
#include "slam/io/g2o_io.h"
#include "tests/data_paths.h"

namespace certislam::certify {
namespace {

constexpr double kSmallGridOptimum = 1025.39802075;  // data/g2o/README.md (SE-Sync)
constexpr double kRelCostTol = 1e-6;
constexpr int kMaxRounds = 200;

// The team's f at the rounds' last iterate.
double Cost(InMemoryTeam* team) {
    double f = 0.0;
    for (auto& me : team->robots) f += me.Evaluate().cost;
    return f;
}

// The team's Riemannian gradient norm at the rounds' last iterate (from the block gradients).
double GradientNorm(InMemoryTeam* team) {
    double sq = 0.0;
    for (auto& me : team->robots) sq += std::pow(me.Evaluate().grad_norm, 2);
    return std::sqrt(sq);
}

std::vector<slam::RobotGraph> SmallGrid(int robots) {
    const auto read = slam::ReadG2o(test_data::G2oPath("smallGrid3D.g2o"));
    EXPECT_EQ(read.status, slam::PoseGraphReadResult::Status::kOk) << read.error;
    return slam::SplitGraph(read.graph, slam::ContiguousPartition(read.graph.n, robots));
}

TEST(TeamRounds, ThreeRobotsReachTheOptimumAndAgree) {
    InMemoryTeam team = RunTeamRoundsInMemory(SmallGrid(3), SolverConfig{}, TeamRoundsConfig{});
    for (size_t i = 0; i < team.robots.size(); ++i) {
        EXPECT_TRUE(team.converged[i]) << "robot " << i;
        EXPECT_EQ(team.rounds[i], team.rounds.front());
        EXPECT_EQ(team.restarts[i], team.restarts.front());
    }
    EXPECT_NEAR(Cost(&team), kSmallGridOptimum, kRelCostTol * kSmallGridOptimum);
    EXPECT_LE(team.rounds.front(), std::uint64_t{kMaxRounds});
}

TEST(TeamRounds, AccelerationNeedsFewerRoundsThanPlainSweeps) {
    TeamRoundsConfig off;
    off.acceleration = false;
    InMemoryTeam fast = RunTeamRoundsInMemory(SmallGrid(5), SolverConfig{}, TeamRoundsConfig{});
    InMemoryTeam plain = RunTeamRoundsInMemory(SmallGrid(5), SolverConfig{}, off);
    EXPECT_TRUE(fast.AllConverged());
    EXPECT_TRUE(plain.AllConverged());
    EXPECT_NEAR(Cost(&fast), kSmallGridOptimum, kRelCostTol * kSmallGridOptimum);
    EXPECT_NEAR(Cost(&plain), kSmallGridOptimum, kRelCostTol * kSmallGridOptimum);
    EXPECT_LT(fast.rounds.front(), plain.rounds.front());
    EXPECT_EQ(plain.restarts.front(), 0);
}

TEST(TeamRounds, RefinementGoesBelowTheFirstOrderToleranceForAtMostItsRounds) {
    constexpr int kBudget = 5;
    TeamRoundsConfig none, unreachable, config;
    none.refine_rounds = 0;
    unreachable.refine_rel_grad_tol = 1e-30;
    unreachable.refine_rounds = kBudget;
    InMemoryTeam first_order = RunTeamRoundsInMemory(SmallGrid(5), SolverConfig{}, none);
    InMemoryTeam capped = RunTeamRoundsInMemory(SmallGrid(5), SolverConfig{}, unreachable);
    InMemoryTeam refined = RunTeamRoundsInMemory(SmallGrid(5), SolverConfig{}, config);
    for (const auto* team : {&first_order, &capped, &refined}) EXPECT_TRUE(team->AllConverged());
    const double f = Cost(&refined);
    EXPECT_LE(GradientNorm(&first_order), none.rel_grad_tol * f);
    EXPECT_GT(GradientNorm(&first_order), config.refine_rel_grad_tol * f);
    EXPECT_GE(capped.rounds.front(), first_order.rounds.front() + kBudget);
    EXPECT_LE(GradientNorm(&capped), unreachable.rel_grad_tol * Cost(&capped));
    EXPECT_LE(GradientNorm(&refined), config.refine_rel_grad_tol * f);
    EXPECT_GT(refined.rounds.front(), first_order.rounds.front());
    EXPECT_LE(refined.rounds.front(),
              first_order.rounds.front() + static_cast<std::uint64_t>(config.refine_rounds));
}

// Scripted sums of a one-robot team: every round lowers f, but the gradient, within rel_grad_tol
// at round 1, rises again at rounds 2-5; the spent refinement budget alone must not end the
// rounds at such a point (the certificate's bound grows with the gradient).
TEST(TeamRounds, SpentRefinementEndsOnlyWithinTheFirstOrderTolerance) {
    TeamRoundsConfig config;
    config.refine_rounds = 2;
    config.acceleration = false;
    TeamRounds rounds(0, {0}, {}, config);
    const Eigen::MatrixXd block = Eigen::MatrixXd::Zero(3, 4);
    const auto cost = [](std::uint64_t r) { return 100.0 - static_cast<double>(r); };
    const auto grad = [&](std::uint64_t r) {
        return (r == 1 || r >= 6 ? 0.1 : 100.0) * config.rel_grad_tol * cost(r);
    };
    std::uint64_t converged_at = 0;
    for (int step = 0; step < 100 && converged_at == 0; ++step) {
        const RoundAction a = rounds.Next();
        using K = RoundAction::Kind;
        if (a.kind == K::kAlign || a.kind == K::kSweep) {
            rounds.SweepDone(a.round, block);
        } else if (a.kind == K::kEvaluate) {
            rounds.OnSums(0, a.round, cost(a.round), grad(a.round));
        } else {
            ASSERT_EQ(a.kind, K::kConverged) << "step " << step;
            converged_at = a.round;
        }
    }
    EXPECT_EQ(converged_at, 6u);
}

TEST(TeamRounds, RefusesABadConfiguration) {
    TeamRoundsConfig bad;
    bad.max_rounds = 0;
    EXPECT_THROW(TeamRounds(0, {0, 1}, {1}, bad), std::invalid_argument);
    TeamRoundsConfig loose_refinement;
    loose_refinement.refine_rel_grad_tol = 2.0 * loose_refinement.rel_grad_tol;
    EXPECT_THROW(TeamRounds(0, {0, 1}, {1}, loose_refinement), std::invalid_argument);
    TeamRoundsConfig negative_budget;
    negative_budget.refine_rounds = -1;
    EXPECT_THROW(TeamRounds(0, {0, 1}, {1}, negative_budget), std::invalid_argument);
}

// Robots 0 - 1 - 2 in a chain: the greedy colours are 0, 1, 0, so in round 1 both ends sweep at
// once (from robot 1's extrapolated poses) and robot 1 waits for both ends; in id order robot 2
// would wait for robot 1.
TEST(TeamRounds, AChainSweepsInTwoColours) {
    const std::vector<int> robots{0, 1, 2};
    const std::map<int, std::set<int>> neighbours{{0, {1}}, {1, {0, 2}}, {2, {1}}};
    std::vector<TeamRounds> team;
    for (int r : robots) team.emplace_back(r, robots, neighbours.at(r), TeamRoundsConfig{});
    const Eigen::MatrixXd block = Eigen::MatrixXd::Zero(5, 4);
    const auto sweep = [&](int r, std::uint64_t round) {
        team[r].SweepDone(round, block);
        PoseBlocks poses;
        poses.ids = {{r, 0}};
        poses.blocks = block;
        poses.sweep_color = team[r].SweepColor();
        for (int peer : neighbours.at(r)) team[peer].OnPoses(r, round, poses);
    };
    using K = RoundAction::Kind;
    for (int r : robots) {  // round 0: placement in id order
        ASSERT_EQ(team[r].Next().kind, K::kAlign) << "robot " << r;
        sweep(r, 0);
    }
    EXPECT_EQ(team[0].SweepColor(), 0);
    EXPECT_EQ(team[1].SweepColor(), 1);
    EXPECT_EQ(team[2].SweepColor(), 0);
    for (int r : robots) {  // round 0's sums: far from converged
        ASSERT_EQ(team[r].Next().kind, K::kEvaluate) << "robot " << r;
        for (auto& peer : team) peer.OnSums(r, 0, 1.0, 1.0);
    }
    EXPECT_EQ(team[0].Next().kind, K::kSweep);
    EXPECT_EQ(team[2].Next().kind, K::kSweep);
    EXPECT_EQ(team[1].Next().kind, K::kWait);
    sweep(2, 1);
    EXPECT_EQ(team[1].Next().kind, K::kWait);  // robot 0 has not swept round 1 yet
    sweep(0, 1);
    const RoundAction middle = team[1].Next();
    EXPECT_EQ(middle.kind, K::kSweep);
    EXPECT_EQ(middle.round, 1u);
}

}  // namespace
}  // namespace certislam::certify
