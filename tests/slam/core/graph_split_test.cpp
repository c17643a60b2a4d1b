// SplitGraph: a hand-built 3D graph split into robots keeps every edge once (intra, inter with
// the tail's robot, shared with the head's), maps ids to robot-local indices, merges parallel
// edges exactly and refuses bad partitions; a planar graph is split as its lift into SE(3).
#include "slam/core/graph_split.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <stdexcept>

namespace certislam::slam {
namespace {

RelativePoseMeasurement Edge(int i, int j, double x) {
    RelativePoseMeasurement e;
    e.i = i;
    e.j = j;
    e.R = Eigen::Matrix3d::Identity();
    e.t = Eigen::Vector3d(x, 0.0, 0.0);
    e.kappa = 2.0 + i;
    e.tau = 3.0 + j;
    return e;
}

/// A chain 0-1-2-3-4 (1 m steps) and a loop 4 -> 0.
PoseGraph Chain() {
    PoseGraph g;
    g.d = 3;
    g.n = 5;
    for (int i = 0; i < 4; ++i) g.edges.push_back(Edge(i, i + 1, 1.0));
    g.edges.push_back(Edge(4, 0, -4.0));
    return g;
}

TEST(SplitGraph, EveryEdgeLandsWithItsRobotsInLocalIds) {
    const auto robots = SplitGraph(Chain(), Partition{{0, 2, 5}});
    ASSERT_EQ(robots.size(), 2u);
    EXPECT_EQ(robots[0].initial.size(), 2u);
    EXPECT_EQ(robots[1].initial.size(), 3u);
    EXPECT_EQ(robots[0].intra.size(), 1u);  // 0-1
    EXPECT_EQ(robots[1].intra.size(), 2u);  // 2-3, 3-4
    ASSERT_EQ(robots[0].inter.size(), 1u);  // 1 -> 2
    EXPECT_EQ(robots[0].inter[0].a, (PoseId{0, 1}));
    EXPECT_EQ(robots[0].inter[0].b, (PoseId{1, 0}));
    ASSERT_EQ(robots[1].inter.size(), 1u);  // 4 -> 0
    EXPECT_EQ(robots[1].inter[0].a, (PoseId{1, 2}));
    EXPECT_EQ(robots[1].inter[0].b, (PoseId{0, 0}));
    EXPECT_DOUBLE_EQ(robots[1].inter[0].kappa, 2.0 + 4);
    EXPECT_DOUBLE_EQ(robots[1].inter[0].tau, 3.0 + 0);
    EXPECT_EQ(robots[0].shared.size(), 1u);
    EXPECT_EQ(robots[1].shared.size(), 1u);
    // No VERTEX lines: the chain composed from pose 0.
    EXPECT_NEAR(robots[1].initial[2].translation().x(), 4.0, 1e-12);
}

TEST(SplitGraph, VertexGuessesAreUsedWhenTheGraphHasThem) {
    PoseGraph g = Chain();
    Eigen::MatrixXd guess = Eigen::MatrixXd::Zero(3, 4 * g.n);
    for (int k = 0; k < g.n; ++k) {
        guess.block<3, 3>(0, 4 * k).setIdentity();
        guess(1, 4 * k + 3) = 10.0 * k;
    }
    g.initial_guess = guess;
    const auto robots = SplitGraph(g, Partition{{0, 2, 5}});
    EXPECT_NEAR(robots[1].initial[1].translation().y(), 30.0, 1e-12);
}

TEST(SplitGraph, RefusesBadPartitions) {
    EXPECT_THROW(SplitGraph(Chain(), Partition{{0, 2, 4}}), std::invalid_argument);
    EXPECT_THROW(SplitGraph(Chain(), Partition{{0, 2, 2, 5}}), std::invalid_argument);
}

/// MATH.md's objective with ||R_i R~||^2 counted as d (SE-Sync's Q, slam::ConnectionLaplacian).
double Cost(const PoseGraph& g, const std::vector<Eigen::Isometry3d>& T) {
    double f = 0.0;
    for (const auto& e : g.edges) {
        const Eigen::Matrix3d Ri = T[e.i].linear(), Rj = T[e.j].linear();
        f += e.kappa * (6.0 - 2.0 * (Rj.transpose() * Ri * e.R).trace()) +
             e.tau * (T[e.j].translation() - T[e.i].translation() - Ri * e.t).squaredNorm();
    }
    return f;
}

/// The chain with two more measurements of 1 -> 2 (other rotations and translations, other
/// weights) and one of 2 -> 1.
PoseGraph WithParallelEdges() {
    PoseGraph g = Chain();
    for (const double angle : {0.3, -0.5}) {
        RelativePoseMeasurement e = Edge(1, 2, 1.0 + angle);
        e.R = Eigen::AngleAxisd(angle, Eigen::Vector3d(1.0, 2.0, 3.0).normalized()).matrix();
        e.t.y() = angle;
        e.kappa = 5.0 - angle;
        e.tau = 2.0 + angle;
        g.edges.push_back(e);
    }
    g.edges.push_back(Edge(2, 1, -1.0));
    return g;
}

TEST(MergeParallelEdges, SameCostAsTheFileUpToItsConstantAtAnyPoses) {
    const PoseGraph file = WithParallelEdges();
    const MergedGraph merged = MergeParallelEdges(file);
    EXPECT_EQ(merged.merged, 2);
    ASSERT_EQ(merged.graph.edges.size(), 6u);  // 1 -> 2 once; 2 -> 1 is another edge
    EXPECT_EQ(merged.graph.edges[5].i, 2);
    EXPECT_NEAR(merged.graph.edges[1].kappa, (2.0 + 1.0) + (5.0 - 0.3) + (5.0 + 0.5), 1e-12);
    double offset = 0.0;
    for (const double c : merged.cost) offset += c;
    EXPECT_GT(offset, 0.1);  // the three translations differ
    EXPECT_EQ(merged.cost[0], 0.0);
    // Any poses: the rotation terms are linear in kappa R~, the translation terms differ by the
    // constant alone.
    for (int trial = 0; trial < 5; ++trial) {
        std::vector<Eigen::Isometry3d> T(file.n);
        for (int k = 0; k < file.n; ++k) {
            const Eigen::Vector3d axis(std::sin(k + trial), std::cos(2.0 * k), 0.5 + trial);
            T[k] = Eigen::Translation3d(Eigen::Vector3d(k, trial - 2.0 * k, 0.3 * k)) *
                   Eigen::AngleAxisd(0.7 * k + trial, axis.normalized());
        }
        EXPECT_NEAR(Cost(file, T), Cost(merged.graph, T) + offset, 1e-9 * Cost(file, T));
    }
}

TEST(SplitGraph, MergesParallelEdgesAndGivesTheTailItsConstant) {
    const PoseGraph file = WithParallelEdges();
    const MergedGraph merged = MergeParallelEdges(file);
    const auto robots = SplitGraph(file, Partition{{0, 2, 5}});
    ASSERT_EQ(robots[0].inter.size(), 1u);   // 1 -> 2, merged
    EXPECT_EQ(robots[0].shared.size(), 2u);  // 2 -> 1 and 4 -> 0
    EXPECT_NEAR(robots[0].inter[0].kappa, merged.graph.edges[1].kappa, 1e-12);
    EXPECT_NEAR((robots[0].inter[0].T_a_b.linear() - merged.graph.edges[1].R).norm(), 0.0, 1e-12);
    EXPECT_NEAR(robots[0].cost_offset, merged.cost[1], 1e-12);
    EXPECT_EQ(robots[1].cost_offset, 0.0);
    EXPECT_NEAR(CostOffset(robots), merged.cost[1], 1e-12);
    // The chain's initial guess uses the file's first 1 -> 2 measurement, a rotation.
    EXPECT_NEAR(robots[1].initial[0].translation().x(), 2.0, 1e-12);
}

}  // namespace
}  // namespace certislam::slam

namespace certislam::slam {
namespace {

/// A planar triangle with a 90 degree turn per edge and a VERTEX guess.
PoseGraph PlanarTriangle() {
    PoseGraph g;
    g.d = 2;
    g.n = 3;
    for (int i = 0; i < 3; ++i) {
        RelativePoseMeasurement e;
        e.i = i;
        e.j = (i + 1) % 3;
        e.R = Eigen::Rotation2Dd(0.5 * M_PI).toRotationMatrix();
        e.t = Eigen::Vector2d(1.0 + i, -0.5);
        e.kappa = 4.0 + i;
        e.tau = 7.0 - i;
        g.edges.push_back(e);
    }
    Eigen::MatrixXd guess = Eigen::MatrixXd::Zero(2, 3 * g.n);
    for (int k = 0; k < g.n; ++k) {
        guess.block<2, 2>(0, 3 * k) = Eigen::Rotation2Dd(0.3 * k).toRotationMatrix();
        guess.block<2, 1>(0, 3 * k + 2) = Eigen::Vector2d(k, 2.0 * k);
    }
    g.initial_guess = guess;
    return g;
}

TEST(LiftPlanar, RotationsAboutZAtZeroHeightWithTheSameWeights) {
    const PoseGraph planar = PlanarTriangle();
    const PoseGraph lifted = LiftPlanar(planar);
    ASSERT_EQ(lifted.d, 3);
    ASSERT_EQ(lifted.edges.size(), planar.edges.size());
    for (size_t k = 0; k < planar.edges.size(); ++k) {
        const auto& e = lifted.edges[k];
        EXPECT_TRUE(e.R.topLeftCorner(2, 2).isApprox(planar.edges[k].R));
        EXPECT_EQ(e.R.col(2), Eigen::Vector3d::UnitZ());
        EXPECT_EQ(e.R.row(2), Eigen::RowVector3d::UnitZ());
        EXPECT_EQ(e.t, Eigen::Vector3d(planar.edges[k].t(0), planar.edges[k].t(1), 0.0));
        EXPECT_EQ(e.kappa, planar.edges[k].kappa);
        EXPECT_EQ(e.tau, planar.edges[k].tau);
    }
    ASSERT_TRUE(lifted.initial_guess.has_value());
    EXPECT_NEAR((*lifted.initial_guess)(1, 4 * 2 + 3), 4.0, 1e-15);
    EXPECT_EQ((*lifted.initial_guess)(2, 4 * 2 + 3), 0.0);
    EXPECT_NEAR((*lifted.initial_guess)(1, 4 * 1), std::sin(0.3), 1e-15);
    // A split of the planar graph is the split of its lift.
    const auto robots = SplitGraph(planar, Partition{{0, 1, 3}});
    ASSERT_EQ(robots.size(), 2u);
    EXPECT_NEAR(robots[1].initial[1].translation().y(), 4.0, 1e-15);
    EXPECT_EQ(robots[1].initial[1].translation().z(), 0.0);
}

}  // namespace
}  // namespace certislam::slam
