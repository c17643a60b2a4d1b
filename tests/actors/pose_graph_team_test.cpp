// A benchmark pose graph split into robots, each robot's real source, solver and certifier
// actors over inproc sockets: the team certifies the optimum the in-process solver finds, also
// with parallel edges (merged before the split).
#include "actors/pose_graph_team.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "certify/pose_graph_solver.h"
#include "slam/io/g2o_io.h"
#include "tests/data_paths.h"

namespace certislam::actors {
namespace {

constexpr double kRelCost = 1e-6;  ///< distributed vs in-process optimum of the file as written
constexpr std::chrono::seconds kTimeout{90};  ///< a team that has not certified by then failed

slam::PoseGraph Read(const std::string& name) {
    const auto read = slam::ReadG2o(test_data::G2oPath(name));
    EXPECT_TRUE(read.ok()) << read.error;
    return read.graph;
}

void ExpectCertifiedOptimum(const PoseGraphTeamResult& team,
                            const std::vector<slam::RobotGraph>& graphs, double central_cost,
                            const std::string& name, int robots) {
    ASSERT_TRUE(team.done) << name << " in " << robots << " robots: not certified in time";
    ASSERT_TRUE(team.report.has_value());
    EXPECT_EQ(team.report->verdict(), v1::CERTIFICATE_VERDICT_CERTIFIED);
    EXPECT_DOUBLE_EQ(team.cost_offset, slam::CostOffset(graphs));
    const double cost = team.report->objective() + team.cost_offset;
    EXPECT_LE(std::abs(cost - central_cost) / central_cost, kRelCost)
        << "distributed " << cost << " vs in-process " << central_cost;
    EXPECT_EQ(static_cast<int>(team.iterations_by_robot.size()), robots);
    EXPECT_GT(team.iterations, 0u);
    EXPECT_GE(team.certificate_rounds, 1);
    EXPECT_GT(team.lanczos_steps, 0u);
    // Robots share inter-robot edges and public poses, and certify together: bytes cross.
    EXPECT_GT(team.bytes_by_actor.at("solver"), 0u);
    EXPECT_GT(team.bytes_by_actor.at("certifier"), 0u);
    EXPECT_GT(team.bytes_by_actor.at("pose_graph"), 0u);
    EXPECT_EQ(team.bytes_between_robots, team.bytes_by_actor.at("solver") +
                                             team.bytes_by_actor.at("certifier") +
                                             team.bytes_by_actor.at("pose_graph"));
}

/// The file's measurement rotations (non-unit quaternions as written, merged parallel edges) go
/// over the wire as they are, so the team solves the file's problem: cost within kRelCost.
PoseGraphTeamResult ExpectTeamCertifiesTheOptimum(const slam::PoseGraph& graph,
                                                  const std::string& name, int robots,
                                                  PoseGraphNodeConfig config = {}) {
    const auto central = certify::SolvePoseGraph(graph);
    EXPECT_EQ(central.status, certify::PoseGraphSolverResult::Status::kCertified);

    config.quiet = std::chrono::milliseconds(300);
    const auto graphs = slam::SplitGraph(graph, slam::ContiguousPartition(graph.n, robots));
    PoseGraphTeamResult team = RunPoseGraphTeam(graphs, config, kTimeout);
    ExpectCertifiedOptimum(team, graphs, central.cost, name, robots);
    return team;
}

TEST(PoseGraphTeam, TinyGridInTwoRobotsCertifiesTheInProcessOptimum) {
    ExpectTeamCertifiesTheOptimum(Read("tinyGrid3D.g2o"), "tinyGrid3D.g2o", 2);
}

TEST(PoseGraphTeam, SmallGridInFiveRobotsCertifiesTheInProcessOptimum) {
    ExpectTeamCertifiesTheOptimum(Read("smallGrid3D.g2o"), "smallGrid3D.g2o", 5);
}

/// smallGrid3D with a second, disagreeing measurement of every fifth edge (same direction) and
/// the reverse of every seventh: the robots hold the merged edges and certify the file's optimum.
TEST(PoseGraphTeam, ParallelEdgesInFiveRobotsCertifyTheInProcessOptimum) {
    slam::PoseGraph graph = Read("smallGrid3D.g2o");
    const size_t m = graph.edges.size();
    for (size_t k = 0; k < m; ++k) {
        slam::RelativePoseMeasurement e = graph.edges[k];
        if (k % 5 == 0) {
            e.R = e.R * Eigen::AngleAxisd(0.05, Eigen::Vector3d::UnitZ()).toRotationMatrix();
            e.t += Eigen::Vector3d(0.1, -0.05, 0.02);
            e.tau *= 0.5;
            graph.edges.push_back(e);
        } else if (k % 7 == 0) {
            const Eigen::Matrix3d R = e.R;
            std::swap(e.i, e.j);
            e.R = R.transpose();
            e.t = -(R.transpose() * e.t);
            graph.edges.push_back(e);
        }
    }
    ASSERT_GT(slam::MergeParallelEdges(graph).merged, 0);
    ExpectTeamCertifiesTheOptimum(graph, "smallGrid3D.g2o with parallel edges", 5);
}

// Rounds cut at 3 (solver.rounds_max) hand the team to its second-order finish:
// the robots' finish messages over inproc take it to the optimum, which the team certifies.
TEST(PoseGraphTeam, TheFinishAfterThreeRoundsCertifiesTheInProcessOptimum) {
    PoseGraphNodeConfig config;
    config.solver.rounds.max_rounds = 3;
    const PoseGraphTeamResult team =
        ExpectTeamCertifiesTheOptimum(Read("smallGrid3D.g2o"), "smallGrid3D.g2o", 5, config);
    EXPECT_EQ(team.finish_status, "converged");
    EXPECT_GE(team.finish_steps, 1);
    EXPECT_GT(team.finish_cg_iterations, 0);
    EXPECT_GE(team.finish_exchanges, std::uint64_t(team.finish_cg_iterations));
    EXPECT_GT(team.finish_reductions, 0u);
    EXPECT_GT(team.finish_seconds, 0.0);
    EXPECT_EQ(team.finish_dropped, 0u);
    EXPECT_EQ(team.solver_mode, "synchronous");  // no robot went on asynchronously
    // Three sweeps and the finish's block: nothing more moved any robot's block.
    for (const auto& [robot, steps] : team.iterations_by_robot) EXPECT_EQ(steps, 4u) << robot;
}

// Without the finish (0) the same rounds run to their tolerance and the finish never starts.
TEST(PoseGraphTeam, NoFinishWhenTheRoundsConvergeFirst) {
    PoseGraphNodeConfig config;
    config.solver.finish_after_rounds = 0;
    const PoseGraphTeamResult team =
        ExpectTeamCertifiesTheOptimum(Read("smallGrid3D.g2o"), "smallGrid3D.g2o", 5, config);
    EXPECT_EQ(team.finish_status, "");
    EXPECT_EQ(team.finish_cg_iterations, 0);
    EXPECT_GT(team.iterations, 3u);
}

}  // namespace
}  // namespace certislam::actors
