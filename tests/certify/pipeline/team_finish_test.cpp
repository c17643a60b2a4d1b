// The team's second-order finish: robots' TeamFinish driven from messages alone (every message
// handed over at once) reach the published optimum from where the rounds stopped, agree on every
// decision, and end (never hang) on a peer's malformed sums.
#include "certify/pipeline/team_finish.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
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

// Every robot's counters but the entries it sent, and its view of f, bit for bit.
void ExpectSameDecisions(const InMemoryFinish& f) {
    for (const auto& p : f.progress) {
        EXPECT_EQ(p.iterations, f.progress.front().iterations);
        EXPECT_EQ(p.accepted, f.progress.front().accepted);
        EXPECT_EQ(p.tcg_iterations, f.progress.front().tcg_iterations);
        EXPECT_EQ(p.exchanges, f.progress.front().exchanges);
        EXPECT_EQ(p.reductions, f.progress.front().reductions);
        EXPECT_EQ(p.cost, f.progress.front().cost);
        EXPECT_EQ(p.grad_norm, f.progress.front().grad_norm);
        EXPECT_EQ(p.dropped, 0u);
    }
}

TEST(TeamFinish, FromAFewRoundsEveryRobotReachesTheOptimumWithTheSameDecisions) {
    for (int overlap : {0, 1, 2}) {
        InMemoryTeam team = AfterRounds("smallGrid3D.g2o", 4, 3);
        ASSERT_FALSE(team.AllConverged());  // the finish has work to do
        const double before = team.GradientNorm();
        TeamFinishConfig config;
        config.overlap = overlap;
        const InMemoryFinish f = RunTeamFinishInMemory(&team, config);
        EXPECT_TRUE(f.AllConverged()) << "overlap " << overlap;
        ExpectSameDecisions(f);
        const TeamFinishProgress& p = f.progress.front();
        // f = tr(X Q X^T) as the certificate has it; the robots' SolverStates count an edge's
        // rotation term exactly, not as Q does for the file's unnormalised quaternions (1e-7 f).
        EXPECT_NEAR(p.cost, kSmallGridOptimum, 1e-8 * kSmallGridOptimum);
        const double cost = team.Cost();
        EXPECT_NEAR(cost, kSmallGridOptimum, 1e-6 * kSmallGridOptimum) << "overlap " << overlap;
        // Every robot's block, evaluated by its own SolverState against the neighbours' final
        // poses, is critical.
        EXPECT_LE(team.GradientNorm(), 1e-9 * cost);
        EXPECT_LT(team.GradientNorm(), 1e-6 * before);
        // Per trust-region step: one product per CG iteration, a preconditioner before the
        // first (gather and scatter) and after every CG iteration but a last one on the boundary
        // (H delta's entries and the scatter; none without overlap), the candidate; and the
        // starting X.
        const std::uint64_t per_prec = overlap > 0 ? 2 : 0;
        EXPECT_GE(p.exchanges, 1 + std::uint64_t(p.tcg_iterations) + std::uint64_t(p.iterations));
        EXPECT_LE(p.exchanges, 1 + std::uint64_t(p.tcg_iterations) * (1 + per_prec) +
                                   std::uint64_t(p.iterations) * (1 + per_prec));
        EXPECT_EQ(f.edges > 0, overlap > 0);
    }
}

// intel's rounds crawl (hundreds of rounds in 5 robots); the finish takes over after 20.
TEST(TeamFinish, IntelIsFinishedWhereTheRoundsCrawl) {
    InMemoryTeam team = AfterRounds("intel.g2o", 5, 20);
    ASSERT_FALSE(team.AllConverged());
    const double before = team.Cost();
    const InMemoryFinish f = RunTeamFinishInMemory(&team, TeamFinishConfig{});
    ASSERT_TRUE(f.AllConverged());
    ExpectSameDecisions(f);
    EXPECT_FALSE(f.progress.front().at_floor);
    EXPECT_LT(team.Cost(), before);
    EXPECT_NEAR(f.progress.front().cost, kIntelOptimum, 1e-6 * kIntelOptimum);
    EXPECT_LE(f.progress.front().grad_norm, 1e-10 * kIntelOptimum);
    EXPECT_LE(team.GradientNorm(), 1e-9 * kIntelOptimum);
}

// Two robots of smallGrid3D driven by hand, every message handed over at once.
struct Pair {
    std::vector<TeamFinish> robots;

    explicit Pair(std::vector<std::vector<slam::LoopClosure>> edges = {}) {
        const InMemoryTeam team = AfterRounds("smallGrid3D.g2o", 2, 2);
        for (size_t i = 0; i < team.robots.size(); ++i) {
            const auto& me = team.robots[i];
            auto own = EdgesTouching(me);
            if (i < edges.size()) own.insert(own.end(), edges[i].begin(), edges[i].end());
            robots.emplace_back(me.robot(), std::vector<int>{0, 1}, me.FullBlock(0).blocks, own,
                                TeamFinishConfig{});
        }
    }
    // Delivers until nothing moves (each vector through `edit` first); returns the messages moved.
    int Deliver(const std::function<void(int from, FinishVector*)>& edit = {}) {
        int moved = 0;
        for (bool more = true; more;) {
            more = false;
            for (int i = 0; i < 2; ++i) {
                for (const auto& e : robots[i].TakeEdges()) {
                    robots[e.to].OnEdges(i, e.poses, e.edges);
                    more = true;
                }
                for (auto& v : robots[i].TakeVectors()) {
                    if (edit) edit(i, &v);
                    robots[v.to].OnVector(i, v.step, v.ids, v.blocks);
                    more = true;
                }
                for (const auto& s : robots[i].TakeSums()) {
                    for (auto& r : robots) r.OnSums(i, s.step, s.values);
                    more = true;
                }
                moved += more ? 1 : 0;
            }
        }
        return moved;
    }
    // Delivers in waves: every message sent so far at once, then what that made the robots send;
    // returns the number of waves (sequential message hops) until nothing moves.
    int Waves() {
        for (int waves = 0;; ++waves) {
            std::vector<std::pair<int, FinishEdges>> edges;
            std::vector<std::pair<int, FinishVector>> vectors;
            std::vector<std::pair<int, FinishSums>> sums;
            for (int i = 0; i < 2; ++i) {
                for (auto& e : robots[i].TakeEdges()) edges.emplace_back(i, std::move(e));
                for (auto& v : robots[i].TakeVectors()) vectors.emplace_back(i, std::move(v));
                for (auto& x : robots[i].TakeSums()) sums.emplace_back(i, std::move(x));
            }
            if (edges.empty() && vectors.empty() && sums.empty()) return waves;
            for (const auto& [i, e] : edges) robots[e.to].OnEdges(i, e.poses, e.edges);
            for (const auto& [i, v] : vectors) robots[v.to].OnVector(i, v.step, v.ids, v.blocks);
            for (const auto& [i, x] : sums) {
                for (auto& r : robots) r.OnSums(i, x.step, x.values);
            }
        }
    }
};

// Message hops, the finish's latency over a network: a trust-region step's start (the gather,
// the first scatter, the candidate and its sums), then three per CG iteration: delta's read,
// H delta's entries with the curvature, the scatter with the preconditioner's sums.
TEST(TeamFinish, ACgIterationTakesThreeMessageHops) {
    Pair pair;
    for (auto& r : pair.robots) r.Start();
    const int waves = pair.Waves();
    const auto& p = pair.robots[0].Progress();
    ASSERT_EQ(pair.robots[0].status(), TeamFinish::Status::kConverged);
    ASSERT_GE(p.tcg_iterations, 2 * p.iterations);  // enough CG for the count to tell
    EXPECT_LE(waves, 2 + 4 * p.iterations + 3 * p.tcg_iterations);
    EXPECT_GE(waves, 2 + 3 * p.tcg_iterations);
}

TEST(TeamFinish, MalformedSumsEndEveryRobotAsInconsistentInsteadOfWaiting) {
    Pair pair;
    pair.robots[0].Start();
    pair.robots[1].Start();
    for (int i = 0; i < 2; ++i) {
        for (const auto& e : pair.robots[i].TakeEdges())
            pair.robots[e.to].OnEdges(i, e.poses, e.edges);
        for (const auto& v : pair.robots[i].TakeVectors())
            pair.robots[v.to].OnVector(i, v.step, v.ids, v.blocks);
    }
    const auto first = pair.robots[0].TakeSums();
    ASSERT_EQ(first.size(), 1u);
    pair.robots[1].TakeSums();  // robot 1's true share is replaced by a short one below
    // A robot outside the team, a sum far ahead: dropped and counted; nothing decided.
    pair.robots[0].OnSums(7, first[0].step, first[0].values);
    pair.robots[0].OnSums(1, first[0].step + 5, first[0].values);
    EXPECT_EQ(pair.robots[0].Progress().dropped, 2u);
    for (auto& r : pair.robots) r.OnSums(0, first[0].step, first[0].values);
    EXPECT_FALSE(pair.robots[0].Done());
    for (auto& r : pair.robots) r.OnSums(1, first[0].step, {1.0});
    for (auto& r : pair.robots) EXPECT_EQ(r.status(), TeamFinish::Status::kInconsistent);
}

TEST(TeamFinish, EntriesOfAnotherRankOrNotFiniteOrOfAThirdRobotAreDropped) {
    Pair pair;
    pair.robots[0].Start();
    const auto sent = pair.robots[0].TakeVectors();
    ASSERT_EQ(sent.size(), 1u);
    const FinishVector& v = sent[0];
    Eigen::MatrixXd nan = v.blocks;
    nan(0, 0) = std::numeric_limits<double>::quiet_NaN();
    std::vector<slam::PoseId> third = v.ids;
    third[0].robot = 5;
    pair.robots[1].OnVector(0, v.step, v.ids, nan);
    pair.robots[1].OnVector(0, v.step, v.ids, v.blocks.topRows(v.blocks.rows() - 1));
    pair.robots[1].OnVector(0, v.step, third, v.blocks);
    pair.robots[1].OnVector(0, v.step + 9, v.ids, v.blocks);
    EXPECT_EQ(pair.robots[1].Progress().dropped, 4u);
    // The true entries still make the pair converge.
    pair.robots[1].OnVector(0, v.step, v.ids, v.blocks);
    pair.robots[1].Start();
    pair.Deliver();
    EXPECT_EQ(pair.robots[0].status(), TeamFinish::Status::kConverged);
    EXPECT_EQ(pair.robots[1].status(), TeamFinish::Status::kConverged);
}

// Robot 1 holds an edge to a pose of robot 0 that robot 0 does not know: robot 1 cannot build
// its rows, and both robots end together instead of robot 0 waiting for ever.
TEST(TeamFinish, ALocalFailureEndsEveryRobotAtTheSameSum) {
    slam::LoopClosure extra;
    extra.a = {1, 0};
    extra.b = {0, 7};
    Pair pair({{}, {extra}});
    for (auto& r : pair.robots) r.Start();
    EXPECT_GT(pair.Deliver(), 0);
    for (auto& r : pair.robots) {
        EXPECT_EQ(r.status(), TeamFinish::Status::kInconsistent);
        EXPECT_EQ(r.Progress().reductions, 1u);
    }
}

// Robot 1 returns its share of robot 0's preconditioner at a pose robot 0 does not have (its
// first scatter, exchange 2 after the start and the gather): robot 0 goes on with the CG
// iteration's exchanges, and its non-finite share of the next sum (the curvature, the third)
// ends both robots there.
TEST(TeamFinish, AFailureInsideACgIterationEndsEveryRobotAtTheNextSum) {
    Pair pair;
    for (auto& r : pair.robots) r.Start();
    bool edited = false;
    pair.Deliver([&](int from, FinishVector* v) {
        if (from == 1 && v->step == 2 && !v->ids.empty()) {
            v->ids[0].index = 100000;
            edited = true;
        }
    });
    ASSERT_TRUE(edited);
    for (auto& r : pair.robots) {
        EXPECT_EQ(r.status(), TeamFinish::Status::kInconsistent);
        EXPECT_EQ(r.Progress().reductions, 3u);
        EXPECT_EQ(r.Progress().tcg_iterations, 0);  // the first one ends unfinished
    }
}

// Removes a vector's first pose and its columns (4 per pose).
void DropFirstEntry(FinishVector* v) {
    v->ids.erase(v->ids.begin());
    v->blocks = Eigen::MatrixXd(v->blocks.rightCols(v->blocks.cols() - 4));
}

// Robot 1's H delta entries (exchange 4: the first CG iteration's second hop) lack one pose of
// robot 0's domain: robot 0 cannot update that copy of robot 1's r, spoils its share of the
// next sum (the scatter's, the fourth) and both robots end there.
TEST(TeamFinish, AMissingHDeltaEntryEndsEveryRobotAtTheNextSum) {
    Pair pair;
    for (auto& r : pair.robots) r.Start();
    bool edited = false;
    pair.Deliver([&](int from, FinishVector* v) {
        if (from == 1 && v->step == 4 && !v->ids.empty()) {
            DropFirstEntry(v);
            edited = true;
        }
    });
    ASSERT_TRUE(edited);
    for (auto& r : pair.robots) {
        EXPECT_EQ(r.status(), TeamFinish::Status::kInconsistent);
        EXPECT_EQ(r.Progress().reductions, 4u);
        EXPECT_EQ(r.Progress().tcg_iterations, 1);
    }
}

// Robot 0's gather (exchange 1) lacks one pose of robot 1's domain: robot 1's domain solve
// fails, it sends an empty scatter, which robot 0 takes as such, and its non-finite share of the
// scatter's sums (the second) ends both robots there.
TEST(TeamFinish, AFailedDomainSolveSendsAnEmptyScatterAndEndsEveryRobotAtItsSum) {
    Pair pair;
    for (auto& r : pair.robots) r.Start();
    bool edited = false, empty_scatter = false;
    pair.Deliver([&](int from, FinishVector* v) {
        if (from == 0 && v->step == 1 && !v->ids.empty()) {
            DropFirstEntry(v);
            edited = true;
        }
        if (from == 1 && v->step == 2) empty_scatter = v->ids.empty() && v->blocks.cols() == 0;
    });
    ASSERT_TRUE(edited);
    EXPECT_TRUE(empty_scatter);
    for (auto& r : pair.robots) {
        EXPECT_EQ(r.status(), TeamFinish::Status::kInconsistent);
        EXPECT_EQ(r.Progress().reductions, 2u);
        EXPECT_EQ(r.Progress().tcg_iterations, 0);
    }
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
