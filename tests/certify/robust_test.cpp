// GNC-TLS on the real multi-robot tunnels data (many outlier loop closures): the robust solve
// keeps every odometry edge, rejects the loop closures that the least-squares solution cannot
// fit, and the problem on the kept edges is certified.
#include "slam/backend/gnc.h"  // robust mode, tested through SolvePoseGraph (certify/)

#include <gtest/gtest.h>

#include <algorithm>
#include <string>

#include "certify/pose_graph_solver.h"
#include "slam/backend/chordal.h"
#include "slam/core/partition.h"
#include "slam/io/multirobot_io.h"
#include "tests/data_paths.h"

namespace certislam::slam {
namespace {

constexpr int kTunnelPoses = 1255;
constexpr int kTunnelEdges = 4891;
constexpr double kGncInnerTolerance = 1e-4;  ///< rel_grad_tol of the GNC rounds' RBCD
constexpr double kFitFraction = 0.95;        ///< kept edges within c^2, rejected ones above

PoseGraph Tunnels() {
    const PoseGraphReadResult read = ReadMultiRobotCsv(test_data::G2oPath("multirobot/tunnels"));
    EXPECT_TRUE(read.ok()) << read.error;
    return read.graph;
}

TEST(GncTunnels, ReaderKeepsInterRobotEdgesOnce) {
    const PoseGraph graph = Tunnels();
    EXPECT_EQ(graph.n, kTunnelPoses);
    EXPECT_EQ(static_cast<int>(graph.edges.size()), kTunnelEdges);
    EXPECT_EQ(PartitionFromIds(graph).num_robots(), 8);
}

TEST(GncTunnels, RobustSolveRejectsOutliersAndCertifiesTheKeptProblem) {
    const PoseGraph graph = Tunnels();
    certify::PoseGraphSolverConfig config;
    config.robust = true;
    config.robots = 1;
    // The GNC rounds only steer the weights: a looser inner tolerance; the final problem on
    // the kept edges is solved and certified at the default tolerances.
    config.gnc.rbcd.rel_grad_tol = kGncInnerTolerance;
    const certify::PoseGraphSolverResult robust = certify::SolvePoseGraph(graph, config);
    const int kept = robust.edges_used;
    const int known = static_cast<int>(std::count_if(
        graph.edges.begin(), graph.edges.end(), [](const auto& e) { return e.is_known_inlier; }));
    std::printf("tunnels robust: kept %d of %zu edges (%d known inliers), cost %.6g, %s, %.2f s\n",
                kept, graph.edges.size(), known, robust.cost,
                robust.status == certify::PoseGraphSolverResult::Status::kCertified
                    ? "certified"
                    : "not certified",
                robust.seconds);
    EXPECT_GE(kept, known);                                 // odometry is never dropped
    EXPECT_LT(kept, static_cast<int>(graph.edges.size()));  // outliers were rejected
    EXPECT_EQ(robust.status, certify::PoseGraphSolverResult::Status::kCertified);
    // At the robust solution the kept edges fit within the TLS threshold and the rejected ones
    // do not (GNC decides on the previous iterate, so a few sit on the other side).
    const std::vector<double> r2 = EdgeSquaredResiduals(graph, robust.poses);
    const double c2 = config.gnc.threshold * config.gnc.threshold;
    int kept_fit = 0, rejected = 0, rejected_misfit = 0;
    size_t next_kept = 0;  // kept edges are the input's inliers, in input order
    for (size_t e = 0; e < graph.edges.size(); ++e) {
        const auto& k = robust.solved_graph.edges;
        const bool is_kept = next_kept < k.size() && k[next_kept].i == graph.edges[e].i &&
                             k[next_kept].j == graph.edges[e].j &&
                             k[next_kept].t == graph.edges[e].t;
        if (is_kept) {
            ++next_kept;
            kept_fit += r2[e] <= c2;
        } else {
            ++rejected;
            rejected_misfit += r2[e] > c2;
        }
    }
    ASSERT_EQ(next_kept, robust.solved_graph.edges.size());
    EXPECT_GE(kept_fit, kFitFraction * kept);
    EXPECT_GE(rejected_misfit, kFitFraction * rejected);
}

}  // namespace
}  // namespace certislam::slam
