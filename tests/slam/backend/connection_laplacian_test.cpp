// Tests that tr(X Q X^T) is the SE-Sync objective, on hand-built graphs.
#include "slam/backend/connection_laplacian.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <random>

namespace certislam::slam {
namespace {

constexpr double kTol = 1e-9;

Eigen::Matrix3d RandomRotation(std::mt19937& rng) {
    std::normal_distribution<double> g;
    return Eigen::Quaterniond(g(rng), g(rng), g(rng), g(rng)).normalized().toRotationMatrix();
}

PoseGraph RandomGraph(int n, int extra_edges, std::mt19937& rng) {
    PoseGraph graph;
    graph.d = 3;
    graph.n = n;
    std::normal_distribution<double> g;
    std::uniform_int_distribution<int> pick(0, n - 1);
    std::uniform_real_distribution<double> w(0.5, 20.0);
    auto add = [&](int i, int j) {
        RelativePoseMeasurement e;
        e.i = i;
        e.j = j;
        e.R = RandomRotation(rng);
        e.t = Eigen::Vector3d(g(rng), g(rng), g(rng));
        e.kappa = w(rng);
        e.tau = w(rng);
        graph.edges.push_back(e);
    };
    for (int i = 0; i + 1 < n; ++i) add(i, i + 1);
    for (int k = 0; k < extra_edges; ++k) add(pick(rng), pick(rng));
    return graph;
}

TEST(ConnectionLaplacian, TraceFormEqualsObjectiveAtRandomPoses) {
    std::mt19937 rng(7);
    const PoseGraph graph = RandomGraph(12, 20, rng);
    PoseMatrix poses(3, 4 * graph.n);
    std::normal_distribution<double> g;
    for (int k = 0; k < graph.n; ++k) {
        poses.block(0, 4 * k, 3, 3) = RandomRotation(rng);
        poses.col(4 * k + 3) = Eigen::Vector3d(g(rng), g(rng), g(rng));
    }
    const Eigen::SparseMatrix<double> Q = ConnectionLaplacian(graph);
    const double trace_form = (poses * (Q * poses.transpose())).trace();
    const double direct = Objective(graph, poses);
    EXPECT_GT(direct, 1.0);
    EXPECT_NEAR(trace_form, direct, kTol * direct);
}

TEST(ConnectionLaplacian, IsSymmetricPositiveSemidefiniteWithGaugeNullspace) {
    std::mt19937 rng(11);
    const PoseGraph graph = RandomGraph(6, 6, rng);
    const Eigen::MatrixXd Q = Eigen::MatrixXd(ConnectionLaplacian(graph));
    EXPECT_LT((Q - Q.transpose()).norm(), kTol);
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(Q);
    EXPECT_GT(eig.eigenvalues().minCoeff(), -1e-9 * eig.eigenvalues().maxCoeff());
}

TEST(ConnectionLaplacian, ExactMeasurementsGiveZeroCost) {
    // Poses built by composing the measurements along a chain cost exactly zero.
    std::mt19937 rng(3);
    PoseGraph graph = RandomGraph(5, 0, rng);
    PoseMatrix poses(3, 4 * graph.n);
    poses.block(0, 0, 3, 3).setIdentity();
    poses.col(3).setZero();
    for (const auto& e : graph.edges) {
        const Eigen::Matrix3d Ri = poses.block(0, 4 * e.i, 3, 3);
        poses.block(0, 4 * e.j, 3, 3) = Ri * e.R;
        poses.col(4 * e.j + 3) = poses.col(4 * e.i + 3) + Ri * e.t;
    }
    const Eigen::SparseMatrix<double> Q = ConnectionLaplacian(graph);
    EXPECT_NEAR((poses * (Q * poses.transpose())).trace(), 0.0, 1e-9);
    EXPECT_NEAR(Objective(graph, poses), 0.0, 1e-12);
}

}  // namespace
}  // namespace certislam::slam
