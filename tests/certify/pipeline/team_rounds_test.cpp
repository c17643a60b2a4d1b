// Synchronous RBCD++ rounds: robots' SolverStates driven by TeamRounds with every message
// delivered at once reach the published optimum in few rounds, and agree on every decision.
#include "certify/pipeline/team_rounds.h"

#include "certify/pipeline/team_rounds_in_memory.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "slam/core/graph_split.h"
#include "slam/io/g2o_io.h"

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
    const auto read = slam::ReadG2o(std::string(CERTISLAM_DATA_DIR) + "/g2o/smallGrid3D.g2o");
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
    EXPECT_EQ(capped.rounds.front(), first_order.rounds.front() + kBudget);
    EXPECT_LE(GradientNorm(&refined), config.refine_rel_grad_tol * f);
    EXPECT_GT(refined.rounds.front(), first_order.rounds.front());
    EXPECT_LE(refined.rounds.front(),
              first_order.rounds.front() + static_cast<std::uint64_t>(config.refine_rounds));
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

}  // namespace
}  // namespace certislam::certify
