// Synchronous RBCD++ rounds: robots' SolverStates driven by TeamRounds with every message
// delivered at once reach the published optimum in few rounds, and agree on every decision.
#include "certify/pipeline/team_rounds.h"

#include "certify/pipeline/team_rounds_in_memory.h"

#include <gtest/gtest.h>

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

TEST(TeamRounds, RefusesABadConfiguration) {
    TeamRoundsConfig bad;
    bad.max_rounds = 0;
    EXPECT_THROW(TeamRounds(0, {0, 1}, {1}, bad), std::invalid_argument);
}

}  // namespace
}  // namespace certislam::certify
