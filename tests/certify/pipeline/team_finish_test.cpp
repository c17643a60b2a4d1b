// The team's second-order finish: robots' TeamFinish driven from messages alone (every message
// handed over at once) reach the published optimum from where the rounds stopped, agree on every
// decision, and end (never hang) on a peer's malformed sums.
#include "certify/pipeline/team_finish.h"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "certify/pipeline/overlap_sweep.h"
#include "certify/pipeline/team_rounds_in_memory.h"
#include "slam/core/graph_split.h"
#include "slam/io/g2o_io.h"
#include "tests/data_paths.h"

namespace certislam::certify {
namespace {

constexpr double kSmallGridOptimum = 1025.39802075;  // data/g2o/README.md (SE-Sync)
constexpr double kIntelOptimum = 52.3482275928;      // data/g2o/README.md (SE-Sync)

std::vector<slam::RobotGraph> Split(const std::string& file, int robots) {
    const auto read = slam::ReadG2o(test_data::G2oPath(file));
    EXPECT_EQ(read.status, slam::PoseGraphReadResult::Status::kOk) << read.error;
    return slam::SplitGraph(read.graph, slam::ContiguousPartition(read.graph.n, robots));
}

// The robots after `rounds` synchronous rounds (not converged: they give up there).
InMemoryTeam AfterRounds(const std::string& file, int robots, int rounds) {
    TeamRoundsConfig config;
    config.max_rounds = rounds;
    return RunTeamRoundsInMemory(Split(file, robots), SolverConfig{}, config);
}

double Cost(InMemoryTeam* team) {
    double f = 0.0;
    for (auto& me : team->robots) f += me.Evaluate().cost;
    return f;
}

double GradientNorm(InMemoryTeam* team) {
    double sq = 0.0;
    for (auto& me : team->robots) sq += std::pow(me.Evaluate().grad_norm, 2);
    return std::sqrt(sq);
}

TEST(TeamFinish, FromAFewRoundsEveryRobotReachesTheOptimumWithTheSameDecisions) {
    for (int overlap : {0, 2}) {
        InMemoryTeam team = AfterRounds("smallGrid3D.g2o", 4, 3);
        ASSERT_FALSE(team.AllConverged());  // the finish has work to do
        const double before = GradientNorm(&team);
        TeamFinishConfig config;
        config.overlap = overlap;
        const InMemoryFinish f = RunTeamFinishInMemory(&team, config);
        EXPECT_TRUE(f.AllConverged()) << "overlap " << overlap;
        // f = tr(X Q X^T) as the certificate has it; the robots' SolverStates count an edge's
        // rotation term exactly, not as Q does for the file's unnormalised quaternions (1e-7 f).
        EXPECT_NEAR(f.progress.cost, kSmallGridOptimum, 1e-8 * kSmallGridOptimum);
        const double cost = Cost(&team);
        EXPECT_NEAR(cost, kSmallGridOptimum, 1e-6 * kSmallGridOptimum) << "overlap " << overlap;
        // Every robot's block, evaluated by its own SolverState against the neighbours' final
        // poses, is critical.
        EXPECT_LE(GradientNorm(&team), 1e-9 * cost);
        EXPECT_LT(GradientNorm(&team), 1e-6 * before);
        EXPECT_GT(f.progress.tcg_iterations, 0);
        // A product, a preconditioner (two exchanges with overlap) and a candidate per step.
        EXPECT_GE(f.progress.exchanges, std::uint64_t(f.progress.tcg_iterations));
        EXPECT_EQ(f.edges > 0, overlap > 0);
    }
}

// intel's rounds crawl (hundreds of rounds in 5 robots); the finish takes over after 20.
TEST(TeamFinish, IntelIsFinishedWhereTheRoundsCrawl) {
    InMemoryTeam team = AfterRounds("intel.g2o", 5, 20);
    ASSERT_FALSE(team.AllConverged());
    const double before = Cost(&team);
    const InMemoryFinish f = RunTeamFinishInMemory(&team, TeamFinishConfig{});
    ASSERT_TRUE(f.AllConverged());
    EXPECT_FALSE(f.progress.at_floor);
    EXPECT_LT(Cost(&team), before);
    EXPECT_NEAR(f.progress.cost, kIntelOptimum, 1e-6 * kIntelOptimum);
    EXPECT_LE(f.progress.grad_norm, 1e-10 * kIntelOptimum);
    EXPECT_LE(GradientNorm(&team), 1e-9 * kIntelOptimum);
}

// Two robots of smallGrid3D, driven by hand: robot 1's first sums arrive with a wrong length.
TEST(TeamFinish, MalformedSumsEndTheFinishAsInconsistentInsteadOfWaiting) {
    InMemoryTeam team = AfterRounds("smallGrid3D.g2o", 2, 2);
    std::vector<TeamFinish> robots;
    for (const auto& me : team.robots) {
        robots.emplace_back(me.robot(), std::vector<int>{0, 1}, me.FullBlock(0).blocks,
                            EdgesTouching(me), me.NeighbourBlocks(), TeamFinishConfig{});
    }
    robots[0].Start();
    robots[1].Start();
    for (int i = 0; i < 2; ++i) {
        for (const auto& e : robots[i].TakeEdges()) robots[e.to].OnEdges(i, e.poses, e.edges);
    }
    for (int i = 0; i < 2; ++i) {
        for (const auto& v : robots[i].TakeVectors())
            robots[v.to].OnVector(i, v.step, v.ids, v.blocks);
    }
    const auto own = robots[0].TakeSums();
    ASSERT_EQ(own.size(), 1u);
    robots[0].OnSums(0, own[0].step, own[0].values);
    EXPECT_FALSE(robots[0].Done());
    // From a robot outside the team and entries from a non-neighbour: dropped, nothing decided.
    robots[0].OnSums(7, own[0].step, own[0].values);
    robots[0].OnVector(7, 0, {}, Eigen::MatrixXd());
    EXPECT_FALSE(robots[0].Done());
    robots[0].OnSums(1, own[0].step, {1.0});
    EXPECT_EQ(robots[0].status(), TeamFinish::Status::kInconsistent);
}

TEST(TeamFinish, ConfigurationErrorsNameTheField) {
    TeamFinishConfig config;
    config.overlap = 9;
    try {
        config.Validate();
        FAIL() << "overlap 9 accepted";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("TeamFinishConfig.overlap"), std::string::npos);
    }
    config = TeamFinishConfig{};
    config.rel_grad_tol = 0.0;
    EXPECT_THROW(config.Validate(), std::invalid_argument);
}

}  // namespace
}  // namespace certislam::certify
