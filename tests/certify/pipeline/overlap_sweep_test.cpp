// Overlapping sweeps: which poses of later neighbours a robot's domain takes, and what a domain
// update needs.
#include "certify/pipeline/overlap_sweep.h"

#include <gtest/gtest.h>

#include <cstddef>
#include <set>
#include <stdexcept>
#include <vector>

#include "slam/core/graph_split.h"
#include "slam/io/g2o_io.h"
#include "tests/data_paths.h"

namespace certislam::certify {
namespace {

slam::LoopClosure Edge(slam::PoseId a, slam::PoseId b) {
    slam::LoopClosure e;
    e.a = a;
    e.b = b;
    e.T_a_b = Eigen::Isometry3d::Identity();
    return e;
}

// Robots 0 (4 poses), 1 (6 poses) and 2 (4 poses), each a chain, joined end to end:
// 0/3 - 1/0 and 1/5 - 2/0.
std::vector<slam::LoopClosure> ThreeChains() {
    std::vector<slam::LoopClosure> out;
    for (const auto& [robot, n] : std::vector<std::pair<int, int>>{{0, 4}, {1, 6}, {2, 4}}) {
        for (int k = 0; k + 1 < n; ++k) out.push_back(Edge({robot, k}, {robot, k + 1}));
    }
    out.push_back(Edge({0, 3}, {1, 0}));
    out.push_back(Edge({1, 5}, {2, 0}));
    return out;
}

TEST(OverlapDomain, TakesALaterNeighboursPosesWithinTheDepth) {
    const std::set<slam::PoseId> two{{1, 0}, {1, 1}};
    EXPECT_EQ(OverlapDomain(0, ThreeChains(), 2, {1}), two);
    EXPECT_TRUE(OverlapDomain(0, ThreeChains(), 0, {1}).empty());
    EXPECT_TRUE(OverlapDomain(0, ThreeChains(), 2, {}).empty());  // robot 1 sweeps first
}

// Depth 5 reaches 1/0 .. 1/4 from robot 0, not 1/5: it touches robot 2, which is not a later
// neighbour of robot 0 (its pose could not be held fixed).
TEST(OverlapDomain, StopsBeforePosesTouchingOtherRobots) {
    const std::set<slam::PoseId> five{{1, 0}, {1, 1}, {1, 2}, {1, 3}, {1, 4}};
    EXPECT_EQ(OverlapDomain(0, ThreeChains(), 5, {1}), five);
    const std::set<slam::PoseId> first{{1, 0}};
    EXPECT_EQ(OverlapDomain(0, ThreeChains(), 1, {1}), first);
}

TEST(OverlapSweep, NamesADomainPoseItWasNotSent) {
    const auto edges = ThreeChains();
    OverlapSweep sweep(0, 4, 5, edges, OverlapDomain(0, edges, 2, {1}), slam::RbcdConfig{});
    EXPECT_EQ(sweep.OverlapSize(), 2);
    Eigen::MatrixXd X = Eigen::MatrixXd::Zero(5, 16);
    for (int k = 0; k < 4; ++k) X.block<3, 3>(0, 4 * k).setIdentity();
    try {
        sweep.Sweep(X, PoseBlocks{}, 1e-6);
        FAIL() << "no throw";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("pose 1/0"), std::string::npos) << e.what();
    }
}

// Robot 1 of ThreeChains (ends 1/0 and 1/5): at depth 1 it sends the ends, their neighbours and
// pose 0, takes proposals of the ends only and sends the four edges touching them; at depth 2 the
// ends' neighbours may be proposed too.
TEST(RoundBoundary, OfAChainBetweenTwoRobots) {
    SolverConfig config;
    config.odometry_edges = false;
    SolverState me(1, config);
    for (int k = 0; k < 6; ++k) me.AddKeyframe(k, Eigen::Isometry3d::Identity());
    for (const auto& e : ThreeChains()) {
        if (e.a.robot == 1 || e.b.robot == 1) me.AddLoop(e);
    }
    const RoundBoundary one = BoundaryOf(me, 1);
    const std::vector<slam::PoseId> sent{{1, 0}, {1, 1}, {1, 4}, {1, 5}};
    EXPECT_EQ(one.sent, sent);
    EXPECT_EQ(one.proposable, (std::set<int>{0, 5}));
    EXPECT_EQ(one.edges.size(), 4u);
    const RoundBoundary two = BoundaryOf(me, 2);
    EXPECT_EQ(two.sent.size(), 6u);
    EXPECT_EQ(two.proposable, (std::set<int>{0, 1, 4, 5}));
    EXPECT_TRUE(BoundaryOf(me, 0).sent.empty());
}

// Every own pose of robot i that robot j's domain can hold, at any depth and with every other
// robot sweeping after j (the largest domains), is proposable in i's boundary; and the boundary
// bounds the proposals: on sphere2500 in 4 robots, far fewer poses than the block at depth 1.
TEST(RoundBoundary, HoldsEveryPoseANeighboursDomainCanReach) {
    const auto read = slam::ReadG2o(test_data::G2oPath("sphere2500.g2o"));
    ASSERT_EQ(read.status, slam::PoseGraphReadResult::Status::kOk) << read.error;
    const auto graphs = slam::SplitGraph(read.graph, slam::ContiguousPartition(read.graph.n, 4));
    SolverConfig config;
    config.odometry_edges = false;
    std::vector<SolverState> team;
    std::vector<slam::LoopClosure> edges;
    for (const auto& g : graphs) {
        SolverState& me = team.emplace_back(g.robot, config);
        for (size_t k = 0; k < g.initial.size(); ++k) me.AddKeyframe(int(k), g.initial[k]);
        for (const auto* part : {&g.intra, &g.inter, &g.shared}) {
            for (const auto& e : *part) me.AddLoop(e);
        }
        const auto touching = EdgesTouching(me);
        edges.insert(edges.end(), touching.begin(), touching.end());
    }
    for (int depth = 0; depth <= 4; ++depth) {
        for (const auto& me : team) {
            const RoundBoundary boundary = BoundaryOf(me, depth);
            if (depth == 0) {
                EXPECT_TRUE(boundary.proposable.empty());
            } else if (depth == 1) {
                EXPECT_LT(4 * boundary.proposable.size(), size_t(me.NumPoses()));
            }
            for (const auto& j : team) {
                std::set<int> later;
                for (const auto& other : team) {
                    if (other.robot() != j.robot()) later.insert(other.robot());
                }
                for (const auto& id : OverlapDomain(j.robot(), edges, depth, later)) {
                    if (id.robot != me.robot()) continue;
                    EXPECT_TRUE(boundary.proposable.count(id.index))
                        << "depth " << depth << ": robot " << j.robot() << "'s domain holds "
                        << id.robot << "/" << id.index;
                }
            }
        }
    }
}

}  // namespace
}  // namespace certislam::certify
