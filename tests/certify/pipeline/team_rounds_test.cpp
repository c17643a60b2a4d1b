// Synchronous RBCD++ rounds: robots' SolverStates driven by TeamRounds with every message
// delivered at once reach the published optimum in few rounds, and agree on every decision.
#include "certify/pipeline/team_rounds.h"

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

struct Robot {
    SolverState state;
    TeamRounds rounds;
    bool converged = false;
};

// Runs the team until every robot converged or nothing moves; returns the team's f.
double RunTeam(const std::vector<slam::RobotGraph>& graphs, TeamRoundsConfig config,
               std::vector<Robot>* team) {
    std::vector<int> ids;
    for (const auto& g : graphs) ids.push_back(g.robot);
    SolverConfig sc;
    sc.odometry_edges = false;
    for (const auto& g : graphs) {
        SolverState state(g.robot, sc);
        for (size_t k = 0; k < g.initial.size(); ++k) state.AddKeyframe(int(k), g.initial[k]);
        for (const auto& e : g.intra) state.AddLoop(e);
        for (const auto& e : g.inter) state.AddLoop(e);
        for (const auto& e : g.shared) state.AddLoop(e);
        state.LocalChordalStart();
        const auto nbrs = state.Neighbours();
        team->push_back(Robot{std::move(state), TeamRounds(g.robot, ids, nbrs, config)});
    }
    for (bool moved = true; moved;) {
        moved = false;
        for (auto& me : *team) {
            for (RoundAction a = me.rounds.Next();
                 a.kind != RoundAction::Kind::kWait && a.kind != RoundAction::Kind::kGaveUp &&
                 !me.converged;
                 a = me.rounds.Next()) {
                moved = true;
                me.state.SetNeighbourPoses(a.neighbours);
                if (a.kind == RoundAction::Kind::kConverged) {
                    me.state.SetOwnBlock(a.own_start);
                    me.converged = true;
                } else if (a.kind == RoundAction::Kind::kEvaluate) {
                    const auto e = me.state.Evaluate();
                    for (auto& peer : *team) {
                        peer.rounds.OnSums(me.state.robot(), a.round, e.cost, e.grad_norm);
                    }
                } else {
                    if (a.kind == RoundAction::Kind::kAlign) {
                        me.state.AlignToLowerNeighbour();
                    } else {
                        me.state.SetOwnBlock(a.own_start);
                        me.state.StepTo(a.block_tol);
                    }
                    me.rounds.SweepDone(a.round, me.state.FullBlock(0).blocks);
                    const PoseBlocks poses = me.state.PublicPoses(0);
                    for (auto& peer : *team) peer.rounds.OnPoses(me.state.robot(), a.round, poses);
                }
            }
        }
    }
    double f = 0.0;
    for (auto& me : *team) f += me.state.Evaluate().cost;
    return f;
}

std::vector<slam::RobotGraph> SmallGrid(int robots) {
    const auto read = slam::ReadG2o(std::string(CERTISLAM_DATA_DIR) + "/g2o/smallGrid3D.g2o");
    EXPECT_EQ(read.status, slam::PoseGraphReadResult::Status::kOk) << read.error;
    return slam::SplitGraph(read.graph, slam::ContiguousPartition(read.graph.n, robots));
}

TEST(TeamRounds, ThreeRobotsReachTheOptimumAndAgree) {
    std::vector<Robot> team;
    const double f = RunTeam(SmallGrid(3), TeamRoundsConfig{}, &team);
    for (const auto& me : team) {
        EXPECT_TRUE(me.converged) << "robot " << me.state.robot();
        EXPECT_EQ(me.rounds.Rounds(), team.front().rounds.Rounds());
        EXPECT_EQ(me.rounds.Restarts(), team.front().rounds.Restarts());
    }
    EXPECT_NEAR(f, kSmallGridOptimum, kRelCostTol * kSmallGridOptimum);
    EXPECT_LE(team.front().rounds.Rounds(), std::uint64_t{kMaxRounds});
}

TEST(TeamRounds, AccelerationNeedsFewerRoundsThanPlainSweeps) {
    std::vector<Robot> fast, plain;
    TeamRoundsConfig off;
    off.acceleration = false;
    const double f_fast = RunTeam(SmallGrid(5), TeamRoundsConfig{}, &fast);
    const double f_plain = RunTeam(SmallGrid(5), off, &plain);
    EXPECT_NEAR(f_fast, kSmallGridOptimum, kRelCostTol * kSmallGridOptimum);
    EXPECT_NEAR(f_plain, kSmallGridOptimum, kRelCostTol * kSmallGridOptimum);
    EXPECT_LT(fast.front().rounds.Rounds(), plain.front().rounds.Rounds());
    EXPECT_EQ(plain.front().rounds.Restarts(), 0);
}

TEST(TeamRounds, RefusesABadConfiguration) {
    TeamRoundsConfig bad;
    bad.max_rounds = 0;
    EXPECT_THROW(TeamRounds(0, {0, 1}, {1}, bad), std::invalid_argument);
}

}  // namespace
}  // namespace certislam::certify
