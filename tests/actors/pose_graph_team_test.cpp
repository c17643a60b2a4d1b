// A benchmark pose graph split into robots, each robot's real source, solver and certifier
// actors over inproc sockets: the team certifies the optimum the in-process solver finds.
#include "actors/pose_graph_team.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "certify/pose_graph_solver.h"
#include "slam/io/g2o_io.h"

namespace certislam::actors {
namespace {

constexpr double kRelCost = 1e-6;  ///< distributed vs in-process optimum, same measurements
/// Distributed vs the in-process optimum of the file as written: the wire's Pose3 carries unit
/// quaternions, the benchmark files' are within slam::kQuaternionRounding of unit norm.
constexpr double kRelCostAsWritten = 1e-5;
constexpr std::chrono::seconds kTimeout{90};  ///< a team that has not certified by then failed

slam::PoseGraph Read(const std::string& name) {
    const auto read = slam::ReadG2o(std::string(CERTISLAM_DATA_DIR) + "/g2o/" + name);
    EXPECT_TRUE(read.ok()) << read.error;
    return read.graph;
}

/// The graph as the robots receive it: measurement rotations of unit quaternions.
slam::PoseGraph AsOnTheWire(slam::PoseGraph graph) {
    for (auto& e : graph.edges) {
        e.R = Eigen::Quaterniond(Eigen::Matrix3d(e.R)).normalized().toRotationMatrix();
    }
    return graph;
}

void ExpectTeamCertifiesTheOptimum(const std::string& name, int robots) {
    const slam::PoseGraph graph = Read(name);
    const auto as_written = certify::SolvePoseGraph(graph);
    const auto central = certify::SolvePoseGraph(AsOnTheWire(graph));
    ASSERT_EQ(central.status, certify::PoseGraphSolverResult::Status::kCertified);

    PoseGraphNodeConfig config;
    config.quiet = std::chrono::milliseconds(300);
    const auto graphs = slam::SplitGraph(graph, slam::ContiguousPartition(graph.n, robots));
    const PoseGraphTeamResult team = RunPoseGraphTeam(graphs, config, kTimeout);

    ASSERT_TRUE(team.done) << name << " in " << robots << " robots: not certified in time";
    ASSERT_TRUE(team.report.has_value());
    EXPECT_EQ(team.report->verdict(), v1::CERTIFICATE_VERDICT_CERTIFIED);
    EXPECT_LE(std::abs(team.report->objective() - central.cost) / central.cost, kRelCost)
        << "distributed " << team.report->objective() << " vs in-process " << central.cost;
    EXPECT_LE(std::abs(team.report->objective() - as_written.cost) / as_written.cost,
              kRelCostAsWritten);
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

TEST(PoseGraphTeam, TinyGridInTwoRobotsCertifiesTheInProcessOptimum) {
    ExpectTeamCertifiesTheOptimum("tinyGrid3D.g2o", 2);
}

TEST(PoseGraphTeam, SmallGridInFiveRobotsCertifiesTheInProcessOptimum) {
    ExpectTeamCertifiesTheOptimum("smallGrid3D.g2o", 5);
}

}  // namespace
}  // namespace certislam::actors
