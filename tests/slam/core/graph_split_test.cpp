// SplitGraph: a hand-built 3D graph split into robots keeps every edge once (intra, inter with
// the tail's robot, shared with the head's), maps ids to robot-local indices, and refuses what a
// robot's solver cannot hold; a planar graph is split as its lift into SE(3).
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

TEST(SplitGraph, RefusesParallelEdgesAndBadPartitions) {
    PoseGraph parallel = Chain();
    parallel.edges.push_back(Edge(1, 0, -1.0));
    EXPECT_THROW(SplitGraph(parallel, Partition{{0, 2, 5}}), std::invalid_argument);
    EXPECT_THROW(SplitGraph(Chain(), Partition{{0, 2, 4}}), std::invalid_argument);
    EXPECT_THROW(SplitGraph(Chain(), Partition{{0, 2, 2, 5}}), std::invalid_argument);
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
