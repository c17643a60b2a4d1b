// GNC-TLS on a small real grid with one gross outlier loop closure: the outlier is rejected,
// odometry is never rejected, and the kept graph stays connected.
#include "slam/backend/gnc.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <string>

#include "slam/backend/chordal.h"
#include "slam/io/g2o_io.h"
#include "tests/data_paths.h"

namespace certislam::slam {
namespace {

PoseGraph GridWithOutlier(RelativePoseMeasurement* outlier) {
    const PoseGraphReadResult read = ReadG2o(test_data::G2oPath("tinyGrid3D.g2o"));
    EXPECT_TRUE(read.ok()) << read.error;
    PoseGraph graph = read.graph;
    // A 500 m loop closure between the first and the last pose, weighted like the file's edges.
    *outlier = graph.edges.front();
    outlier->i = 0;
    outlier->j = graph.n - 1;
    outlier->R = Eigen::MatrixXd::Identity(3, 3);
    outlier->t = Eigen::Vector3d(500.0, 0.0, 0.0);
    graph.edges.push_back(*outlier);
    return graph;
}

TEST(Gnc, RejectsTheOutlierAndKeepsOdometry) {
    RelativePoseMeasurement outlier;
    const PoseGraph graph = GridWithOutlier(&outlier);
    const Eigen::MatrixXd X0 = LiftToRank(ChordalInitialization(graph), 3);
    const GncResult result = SolveGnc(graph, ContiguousPartition(graph.n, 1), X0);
    ASSERT_EQ(result.inlier.size(), graph.edges.size());
    EXPECT_FALSE(result.inlier.back());  // the 500 m edge
    EXPECT_EQ(result.weights.back(), 0.0);
    int odometry = 0;
    for (size_t e = 0; e + 1 < graph.edges.size(); ++e) {
        if (std::abs(graph.edges[e].i - graph.edges[e].j) != 1) continue;
        EXPECT_TRUE(result.inlier[e]) << "edge " << graph.edges[e].i << "-" << graph.edges[e].j;
        EXPECT_EQ(result.weights[e], 1.0);
        ++odometry;
    }
    EXPECT_EQ(odometry, graph.n - 1);
    EXPECT_LT(result.kept.edges.size(), graph.edges.size());
    EXPECT_TRUE(IsConnected(result.kept));
}

// The grid's own loop closures are inliers (the full graph certifies with every residual below
// the threshold): GNC must keep all of them and reject only the 500 m edge.
TEST(Gnc, KeepsEveryGenuineLoopOfTheGrid) {
    RelativePoseMeasurement outlier;
    const PoseGraph graph = GridWithOutlier(&outlier);
    const Eigen::MatrixXd X0 = LiftToRank(ChordalInitialization(graph), 3);
    const GncResult result = SolveGnc(graph, ContiguousPartition(graph.n, 1), X0);
    ASSERT_EQ(result.inlier.size(), graph.edges.size());
    int loops = 0;
    for (size_t e = 0; e + 1 < graph.edges.size(); ++e) {
        if (std::abs(graph.edges[e].i - graph.edges[e].j) == 1) continue;
        EXPECT_TRUE(result.inlier[e]) << "loop " << graph.edges[e].i << "-" << graph.edges[e].j;
        ++loops;
    }
    EXPECT_GT(loops, 0);
    EXPECT_FALSE(result.inlier.back());
    EXPECT_EQ(result.kept.edges.size(), graph.edges.size() - 1);
    // Without the reinstatement pass the same start loses loops: the test can fail.
    GncConfig plain;
    plain.max_reinstatement_failures = 0;
    const GncResult without = SolveGnc(graph, ContiguousPartition(graph.n, 1), X0, plain);
    EXPECT_LE(without.kept.edges.size(), result.kept.edges.size());
    EXPECT_EQ(result.reinstated,
              static_cast<int>(result.kept.edges.size() - without.kept.edges.size()));
}

// Every loop closure corrupted: GNC may reject all of them, but odometry stays, so the kept
// graph is still connected (a floor on the kept set).
TEST(Gnc, AllLoopClosuresCorruptedStillLeavesAConnectedGraph) {
    RelativePoseMeasurement outlier;
    PoseGraph graph = GridWithOutlier(&outlier);
    for (auto& e : graph.edges) {
        if (std::abs(e.i - e.j) != 1) e.t = Eigen::Vector3d(0.0, 300.0 + e.i, -200.0);
    }
    const Eigen::MatrixXd X0 = LiftToRank(ChordalInitialization(graph), 3);
    const GncResult result = SolveGnc(graph, ContiguousPartition(graph.n, 1), X0);
    EXPECT_TRUE(IsConnected(result.kept));
    EXPECT_GE(static_cast<int>(result.kept.edges.size()), graph.n - 1);
    EXPECT_LT(result.kept.edges.size(), graph.edges.size());  // outliers were rejected
}

}  // namespace
}  // namespace certislam::slam
