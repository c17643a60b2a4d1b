// Synchronous RBCD++ rounds: robots' SolverStates driven by TeamRounds with every message
// delivered at once reach the published optimum in few rounds, and agree on every decision.
#include "certify/pipeline/team_rounds.h"

#include "certify/pipeline/team_rounds_in_memory.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "slam/core/graph_split.h"
#include "slam/io/g2o_io.h"
#include "tests/data_paths.h"

namespace certislam::certify {
namespace {

constexpr double kSmallGridOptimum = 1025.39802075;  // data/g2o/README.md (SE-Sync)
constexpr double kRelCostTol = 1e-6;
constexpr int kMaxRounds = 200;

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
    EXPECT_NEAR(team.Cost(), kSmallGridOptimum, kRelCostTol * kSmallGridOptimum);
    EXPECT_LE(team.rounds.front(), std::uint64_t{kMaxRounds});
}

TEST(TeamRounds, AccelerationNeedsFewerRoundsThanPlainSweeps) {
    TeamRoundsConfig off;
    off.acceleration = false;
    InMemoryTeam fast = RunTeamRoundsInMemory(SmallGrid(5), SolverConfig{}, TeamRoundsConfig{});
    InMemoryTeam plain = RunTeamRoundsInMemory(SmallGrid(5), SolverConfig{}, off);
    EXPECT_TRUE(fast.AllConverged());
    EXPECT_TRUE(plain.AllConverged());
    EXPECT_NEAR(fast.Cost(), kSmallGridOptimum, kRelCostTol * kSmallGridOptimum);
    EXPECT_NEAR(plain.Cost(), kSmallGridOptimum, kRelCostTol * kSmallGridOptimum);
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
    const double f = refined.Cost();
    EXPECT_LE(first_order.GradientNorm(), none.rel_grad_tol * f);
    EXPECT_GT(first_order.GradientNorm(), config.refine_rel_grad_tol * f);
    EXPECT_GE(capped.rounds.front(), first_order.rounds.front() + kBudget);
    EXPECT_LE(capped.GradientNorm(), unreachable.rel_grad_tol * capped.Cost());
    EXPECT_LE(refined.GradientNorm(), config.refine_rel_grad_tol * f);
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

/// Runs one robot's rounds on a gradient that falls by `rate` per round from 1 (f = 100 - round):
/// the round of the kGaveUp, and whether the rounds handed over (0: converged or never ended).
std::pair<std::uint64_t, bool> EndOfLinearRounds(const TeamRoundsConfig& config, double rate) {
    TeamRounds rounds(0, {0}, {}, config);
    const Eigen::MatrixXd block = Eigen::MatrixXd::Zero(3, 4);
    for (int step = 0; step < 20000; ++step) {
        const RoundAction a = rounds.Next();
        using K = RoundAction::Kind;
        if (a.kind == K::kAlign || a.kind == K::kSweep) {
            rounds.SweepDone(a.round, block);
        } else if (a.kind == K::kEvaluate) {
            const double r = static_cast<double>(a.round);
            rounds.OnSums(0, a.round, 100.0 - 1e-3 * r, std::pow(rate, r));
        } else if (a.kind == K::kGaveUp) {
            return {rounds.Rounds(), rounds.HandedOver()};
        } else {
            return {0, false};
        }
    }
    return {0, false};
}

// From hand_over_after on, rounds whose linear rate reaches rel_grad_tol (1e-8 f, f about 100:
// a gradient of 1e-6) only after kHopeless (4) max_rounds end at once; slower ones within that
// margin run to max_rounds, fast ones converge.
TEST(TeamRounds, RoundsTooSlowForMaxRoundsHandOver) {
    TeamRoundsConfig config;
    config.acceleration = false;
    config.max_rounds = 1000;
    config.hand_over_after = 50;
    // 0.999 per round: 1e-6 after 13809 rounds; handed over at the first round allowed.
    EXPECT_EQ(EndOfLinearRounds(config, 0.999), std::make_pair(std::uint64_t{50}, true));
    // 0.99 per round: after 1375 rounds, within the margin: the rounds run to max_rounds.
    EXPECT_EQ(EndOfLinearRounds(config, 0.99), std::make_pair(std::uint64_t{1000}, false));
    // 0.97 per round: after 454 rounds, inside max_rounds: converged.
    EXPECT_EQ(EndOfLinearRounds(config, 0.97), std::make_pair(std::uint64_t{0}, false));
    // Without hand_over_after the hopeless rounds run to max_rounds too.
    config.hand_over_after = 0;
    EXPECT_EQ(EndOfLinearRounds(config, 0.999), std::make_pair(std::uint64_t{1000}, false));
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

// One robot's TeamRounds per robot of a team with the given edges between robots; messages
// are delivered by hand, so a test sees who waits for whom.
struct HandTeam {
    explicit HandTeam(std::map<int, std::set<int>> edges) : neighbours(std::move(edges)) {
        for (const auto& [r, n] : neighbours) robots.push_back(r);
        for (int r : robots) team.emplace(r, TeamRounds(r, robots, neighbours.at(r), {}));
    }
    TeamRounds& operator[](int r) { return team.at(r); }
    /// Robot r's block after its sweep of `round`: distinct per robot and round.
    static Eigen::MatrixXd Block(int r, std::uint64_t round) {
        return Eigen::MatrixXd::Constant(5, 4, 10.0 * r + static_cast<double>(round));
    }
    void Sweep(int r, std::uint64_t round) {
        team.at(r).SweepDone(round, Block(r, round));
        PoseBlocks poses;
        poses.ids = {{r, 0}};
        poses.blocks = Block(r, round);
        poses.sweep_color = team.at(r).SweepColor();
        for (int peer : neighbours.at(r)) team.at(peer).OnPoses(r, round, poses);
    }
    /// Round `round` >= 1: every robot sweeps (colour 0, then the others), then every robot's
    /// sums, `cost` and block gradient norm `grad_norm` each; checks each sweep's overlap flag
    /// against `overlap`.
    void Round(std::uint64_t round, double cost, bool overlap, double grad_norm = 1.0) {
        for (bool later : {false, true}) {
            for (int r : robots) {
                if ((team.at(r).SweepColor() > 0) != later) continue;
                const RoundAction a = team.at(r).Next();
                ASSERT_EQ(a.kind, RoundAction::Kind::kSweep) << "robot " << r << " round " << round;
                EXPECT_EQ(a.overlap, overlap) << "robot " << r << " round " << round;
                Sweep(r, round);
            }
        }
        for (int r : robots) {
            ASSERT_EQ(team.at(r).Next().kind, RoundAction::Kind::kEvaluate) << "robot " << r;
            for (auto& [q, peer] : team) peer.OnSums(r, round, cost, grad_norm);
        }
    }
    /// Round 0: placements in id order, then every robot's sums (far from converged).
    void Place() {
        for (int r : robots) {
            ASSERT_EQ(team.at(r).Next().kind, RoundAction::Kind::kAlign) << "robot " << r;
            Sweep(r, 0);
        }
        for (int r : robots) {
            ASSERT_EQ(team.at(r).Next().kind, RoundAction::Kind::kEvaluate) << "robot " << r;
            for (auto& [q, peer] : team) peer.OnSums(r, 0, 1.0, 1.0);
        }
    }
    std::map<int, std::set<int>> neighbours;
    std::vector<int> robots;
    std::map<int, TeamRounds> team;
};

// Robots 0 - 1 - 2 in a chain: the greedy colours are 0, 1, 0, so in round 1 both ends sweep at
// once (robot 2 from robot 1's round-0 poses) and robot 1 waits for both ends and sweeps from
// their round-1 poses; in id order robot 2 would wait for robot 1.
TEST(TeamRounds, AChainSweepsInTwoColours) {
    HandTeam t({{0, {1}}, {1, {0, 2}}, {2, {1}}});
    t.Place();
    EXPECT_EQ(t[0].SweepColor(), 0);
    EXPECT_EQ(t[1].SweepColor(), 1);
    EXPECT_EQ(t[2].SweepColor(), 0);
    using K = RoundAction::Kind;
    const RoundAction end = t[2].Next();
    ASSERT_EQ(end.kind, K::kSweep);
    EXPECT_EQ(end.neighbours.blocks, HandTeam::Block(1, 0));
    EXPECT_EQ(t[0].Next().kind, K::kSweep);
    EXPECT_EQ(t[1].Next().kind, K::kWait);
    t.Sweep(0, 1);
    EXPECT_EQ(t[1].Next().kind, K::kWait);  // robot 2, the higher end, has not swept round 1
    t.Sweep(2, 1);
    const RoundAction middle = t[1].Next();
    ASSERT_EQ(middle.kind, K::kSweep);
    EXPECT_EQ(middle.round, 1u);
    Eigen::MatrixXd both(5, 8);
    both << HandTeam::Block(0, 1), HandTeam::Block(2, 1);
    EXPECT_EQ(middle.neighbours.blocks, both);
}

// Colours follow ids, not the chain: the path 0 - 2 - 3 - 1 takes colours 0, 0, 1, 2 (robots 0
// and 1 first, then 2, then 3), and a colour's robot waits only for lower colours.
TEST(TeamRounds, ColoursFollowIdsOnAChainNumberedOutOfOrder) {
    HandTeam t({{0, {2}}, {1, {3}}, {2, {0, 3}}, {3, {1, 2}}});
    t.Place();
    EXPECT_EQ(t[0].SweepColor(), 0);
    EXPECT_EQ(t[1].SweepColor(), 0);
    EXPECT_EQ(t[2].SweepColor(), 1);
    EXPECT_EQ(t[3].SweepColor(), 2);
    using K = RoundAction::Kind;
    EXPECT_EQ(t[1].Next().kind, K::kSweep);  // before robot 3, its higher-id neighbour
    EXPECT_EQ(t[2].Next().kind, K::kWait);
    EXPECT_EQ(t[3].Next().kind, K::kWait);
    t.Sweep(0, 1);
    t.Sweep(1, 1);
    EXPECT_EQ(t[2].Next().kind, K::kSweep);
    EXPECT_EQ(t[3].Next().kind, K::kWait);
    t.Sweep(2, 1);
    EXPECT_EQ(t[3].Next().kind, K::kSweep);
}

// A pose of the lifted manifold at rank 5: rotation columns orthonormal, translation t.
Eigen::MatrixXd LiftedPose(double t) {
    Eigen::MatrixXd pose = Eigen::MatrixXd::Zero(5, 4);
    pose.topLeftCorner(3, 3).setIdentity();
    pose.col(3).setConstant(t);
    return pose;
}

// Robot 0's round-1 message: its own pose 0/0 and proposals (pose index, block) for robot 1.
PoseBlocks WithProposals(const std::vector<std::pair<int, Eigen::MatrixXd>>& proposals) {
    PoseBlocks poses;
    poses.ids = {{0, 0}};
    poses.blocks.resize(5, 4 * Eigen::Index(1 + proposals.size()));
    poses.blocks.leftCols(4) = HandTeam::Block(0, 1);
    for (size_t k = 0; k < proposals.size(); ++k) {
        poses.ids.push_back({1, proposals[k].first});
        poses.blocks.middleCols(4 * Eigen::Index(k + 1), 4) = proposals[k].second;
    }
    return poses;
}

// The chain 0 - 1 - 2 placed (robot 1 may take proposals of `proposable`), both ends swept round 1
// and robot 0 sent `message`: robot 1's next action.
RoundAction MiddleAfter(HandTeam& t, const std::optional<std::set<int>>& proposable,
                        const PoseBlocks& message) {
    if (proposable) t[1].SetProposable(*proposable);
    t.Place();
    t.Sweep(2, 1);
    t[0].SweepDone(1, HandTeam::Block(0, 1));
    t[1].OnPoses(0, 1, message);
    return t[1].Next();
}

// An overlapping sweep of robot 0 proposes a pose of robot 1, which sweeps after it: robot 1's
// round starts from the proposal, and the proposal is not among the neighbours' poses it reads.
TEST(TeamRounds, ALaterRobotStartsFromTheProposalOfAnEarlierOne) {
    HandTeam t({{0, {1}}, {1, {0, 2}}, {2, {1}}});
    const RoundAction middle =
        MiddleAfter(t, std::set<int>{0}, WithProposals({{0, LiftedPose(7.0)}}));
    ASSERT_EQ(middle.kind, RoundAction::Kind::kSweep);
    EXPECT_TRUE(middle.overlap);
    EXPECT_EQ(middle.own_start, LiftedPose(7.0));
    EXPECT_EQ(t[1].RejectedProposals(), 0u);
    const std::vector<slam::PoseId> read{{0, 0}, {2, 0}};
    EXPECT_EQ(middle.neighbours.ids, read);
    Eigen::MatrixXd both(5, 8);
    both << HandTeam::Block(0, 1), HandTeam::Block(2, 1);
    EXPECT_EQ(middle.neighbours.blocks, both);
}

// A neighbour's proposals are untrusted: one of a pose its domain cannot hold (not proposable),
// of a pose beyond the block, a block with a NaN, or one whose rotation is not orthonormal is
// dropped and counted, and the sweep starts from the robot's own block.
TEST(TeamRounds, ProposalsOutsideTheReachOrNotPosesAreDroppedAndCounted) {
    HandTeam t({{0, {1}}, {1, {0, 2}}, {2, {1}}});
    Eigen::MatrixXd nan = LiftedPose(7.0), skew = LiftedPose(7.0);
    nan(4, 3) = std::nan("");
    skew(0, 1) = 0.5;
    // Pose 3 is proposable but beyond robot 1's one-pose block.
    const RoundAction middle = MiddleAfter(
        t, std::set<int>{0, 3},
        WithProposals({{1, LiftedPose(7.0)}, {3, LiftedPose(7.0)}, {0, nan}, {0, skew}}));
    ASSERT_EQ(middle.kind, RoundAction::Kind::kSweep);
    EXPECT_EQ(middle.own_start, HandTeam::Block(1, 0));
    EXPECT_EQ(t[1].RejectedProposals(), 4u);
}

// Until the robot says which poses a neighbour may propose, it takes none.
TEST(TeamRounds, NoProposalIsTakenBeforeTheProposablePosesAreSet) {
    HandTeam t({{0, {1}}, {1, {0, 2}}, {2, {1}}});
    const RoundAction middle = MiddleAfter(t, std::nullopt, WithProposals({{0, LiftedPose(7.0)}}));
    ASSERT_EQ(middle.kind, RoundAction::Kind::kSweep);
    EXPECT_EQ(middle.own_start, HandTeam::Block(1, 0));
    EXPECT_EQ(t[1].RejectedProposals(), 1u);
}

// Round 1 has no extrapolation (RBCD++'s first weight is 0): when the team's f rises in it, the
// overlapping sweeps raised it, so every robot drops the round and sweeps own poses from then on.
TEST(TeamRounds, ARoundWithoutExtrapolationWhoseCostRoseEndsTheOverlap) {
    HandTeam t({{0, {1}}, {1, {0, 2}}, {2, {1}}});
    t.Place();              // f = 3 at round 0
    t.Round(1, 2.0, true);  // f = 6
    int sweeps = 0;
    for (int r : t.robots) {
        const RoundAction a = t[r].Next();
        EXPECT_FALSE(t[r].Overlapping()) << "robot " << r;
        EXPECT_EQ(t[r].Restarts(), 1) << "robot " << r;
        if (a.kind == RoundAction::Kind::kSweep) {  // the ends, colour 0
            EXPECT_EQ(a.round, 2u);
            EXPECT_FALSE(a.overlap);
            EXPECT_EQ(a.own_start, HandTeam::Block(r, 0)) << "not from the accepted round 0";
            ++sweeps;
        }
    }
    EXPECT_EQ(sweeps, 2);
    EXPECT_EQ(t[1].OverlapEndedAt(), std::optional<std::uint64_t>(1));
}

// An extrapolated round whose f rose restarts (RBCD++) and keeps the overlap; the plain round
// after it rising too ends it, and a proposal after that is dropped and counted.
TEST(TeamRounds, OnlyARiseWithoutExtrapolationEndsTheOverlap) {
    HandTeam t({{0, {1}}, {1, {0, 2}}, {2, {1}}});
    t[1].SetProposable({0});
    t.Place();                           // f = 3
    t.Round(1, 0.5, true);               // f = 1.5: accepted, the next round extrapolates
    t.Round(2, 1.0, true);               // f = 3: rose with extrapolation
    for (int r : t.robots) t[r].Next();  // each decides round 2
    EXPECT_TRUE(t[1].Overlapping());
    EXPECT_EQ(t[1].Restarts(), 1);
    t.Round(3, 1.0, true);               // plain (after the restart), rose again
    for (int r : t.robots) t[r].Next();  // each decides round 3
    EXPECT_FALSE(t[1].Overlapping());
    EXPECT_EQ(t[1].Restarts(), 2);
    t.Sweep(0, 4);
    t.Sweep(2, 4);
    t[1].OnPoses(0, 4, WithProposals({{0, LiftedPose(7.0)}}));
    const RoundAction middle = t[1].Next();
    ASSERT_EQ(middle.kind, RoundAction::Kind::kSweep);
    EXPECT_FALSE(middle.overlap);
    EXPECT_EQ(t[1].RejectedProposals(), 1u);
}

// Once f is flat (it changed by at most 1e-9 f), a kept extrapolated round whose gradient norm
// rose resets the extrapolation: a restart, and the next round sweeps from that round as it is.
// A falling gradient, or a rising one while f still falls, keeps extrapolating.
TEST(TeamRounds, AGradientRiseWhileTheCostIsFlatResetsTheExtrapolation) {
    struct Case {
        double cost, grad_norm;  // each robot's at round 2 (round 1: 0.5 and 1)
        bool reset;
    };
    for (const Case c : {Case{0.5, 0.5, false}, Case{0.5, 2.0, true}, Case{0.4, 2.0, false}}) {
        HandTeam t({{0, {1}}, {1, {0, 2}}, {2, {1}}});
        t.Place();                              // f = 3
        t.Round(1, 0.5, true);                  // f = 1.5: the next round extrapolates
        t.Round(2, c.cost, true, c.grad_norm);  // f flat or 20 % lower; the gradient 0.5x or 2x
        int sweeps = 0;
        for (int r : t.robots) {
            const RoundAction a = t[r].Next();
            EXPECT_EQ(t[r].Restarts(), c.reset ? 1 : 0) << "robot " << r << " cost " << c.cost;
            if (a.kind != RoundAction::Kind::kSweep) continue;
            ++sweeps;
            EXPECT_EQ(a.round, 3u);
            if (c.reset) {
                EXPECT_EQ(a.own_start, HandTeam::Block(r, 2)) << "round 2 kept, not extrapolated";
            } else {
                EXPECT_NE(a.own_start, HandTeam::Block(r, 2)) << "extrapolated from round 2";
            }
        }
        EXPECT_EQ(sweeps, 2) << "the ends, colour 0";
    }
}

// Two robots on smallGrid3D: overlapping sweeps of depth 4 reach the same optimum in far fewer
// rounds than each robot sweeping its own poses.
TEST(TeamRounds, OverlappingSweepsReachTheOptimumInFewerRounds) {
    TeamRoundsConfig own, overlapping;
    own.overlap_depth = 0;
    overlapping.overlap_depth = 4;
    InMemoryTeam plain = RunTeamRoundsInMemory(SmallGrid(2), SolverConfig{}, own);
    InMemoryTeam fast = RunTeamRoundsInMemory(SmallGrid(2), SolverConfig{}, overlapping);
    ASSERT_TRUE(plain.AllConverged());
    ASSERT_TRUE(fast.AllConverged());
    EXPECT_EQ(fast.rounds[0], fast.rounds[1]);
    // Honest robots propose only poses within the receiver's reach (RoundBoundary::proposable).
    EXPECT_EQ(fast.rejected_proposals, std::vector<std::uint64_t>(2, 0));
    EXPECT_LE(2 * fast.rounds[0], plain.rounds[0]);
    EXPECT_NEAR(fast.Cost(), kSmallGridOptimum, kRelCostTol * kSmallGridOptimum);
}

TEST(TeamRounds, OverlapDepthOutOfRangeIsNamed) {
    TeamRoundsConfig config;
    config.overlap_depth = 17;
    try {
        TeamRounds rounds(0, {0, 1}, {1}, config);
        FAIL() << "no throw";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("overlap_depth = 17"), std::string::npos) << e.what();
    }
}

// Wants() names what Next() waits for (a stalled robot asks their senders for them), Waiting()
// says it in the solver's stall line: round 0's placement waits for the lower neighbour's poses,
// its evaluation for the higher one's, its decision for every other robot's sums; a sweep for
// its earlier neighbour's poses of the round (the later one's of round 0 are in); nothing once
// every action is due.
TEST(TeamRounds, WaitingNamesTheMissingPosesAndSums) {
    TeamRounds rounds(1, {0, 1, 2, 3}, {0, 2}, TeamRoundsConfig{});
    const auto poses_of = [](int robot, int color) {
        PoseBlocks p;
        p.ids = {slam::PoseId{robot, 0}};
        p.blocks = Eigen::MatrixXd::Identity(5, 4);
        p.sweep_color = color;
        return p;
    };
    using W = std::vector<RoundWant>;
    EXPECT_EQ(rounds.Next().kind, RoundAction::Kind::kWait);
    EXPECT_EQ(rounds.Wants(), (W{{0, 0, false}}));
    EXPECT_EQ(rounds.Waiting(), "round 0: the poses of robot 0");
    rounds.OnPoses(0, 0, poses_of(0, 0));
    EXPECT_TRUE(rounds.Wants().empty());
    EXPECT_EQ(rounds.Waiting(), "");  // the placement is due
    ASSERT_EQ(rounds.Next().kind, RoundAction::Kind::kAlign);
    rounds.SweepDone(0, poses_of(1, 1).blocks);
    EXPECT_EQ(rounds.Next().kind, RoundAction::Kind::kWait);
    EXPECT_EQ(rounds.Wants(), (W{{2, 0, false}}));
    EXPECT_EQ(rounds.Waiting(), "round 0: the poses of robot 2");
    rounds.OnPoses(2, 0, poses_of(2, 2));  // colour 2: sweeps after robot 1 (colour 1)
    ASSERT_EQ(rounds.Next().kind, RoundAction::Kind::kEvaluate);
    rounds.OnSums(1, 0, 1.0, 1.0);
    rounds.OnSums(2, 0, 1.0, 1.0);
    EXPECT_EQ(rounds.Next().kind, RoundAction::Kind::kWait);
    EXPECT_EQ(rounds.Wants(), (W{{0, 0, true}, {3, 0, true}}));
    EXPECT_EQ(rounds.Waiting(), "round 0: the sums of robots 0, 3");
    rounds.OnSums(0, 0, 1.0, 1.0);
    rounds.OnSums(3, 0, 1.0, 1.0);
    EXPECT_EQ(rounds.Next().kind, RoundAction::Kind::kWait);
    ASSERT_EQ(rounds.SweepColor(), 1);
    EXPECT_EQ(rounds.Wants(), (W{{0, 1, false}}));
    EXPECT_EQ(rounds.Waiting(), "round 1: the poses of robot 0");
}

}  // namespace
}  // namespace certislam::certify
