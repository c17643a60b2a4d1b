// The distributed certificate (robot-held rows of S, Lanczos over S*v products exchanged between
// neighbours) gives the centralised lambda_min: at a certified optimum of a real file and at a
// known saddle with a negative eigenvalue.
#include "certify/distributed/distributed_certificate.h"

#include <gtest/gtest.h>

#include <string>

#include "certify/certificate.h"
#include "certify/distributed/distributed_lanczos.h"
#include "certify/staircase.h"
#include "slam/backend/chordal.h"
#include "slam/backend/connection_laplacian.h"
#include "slam/io/g2o_io.h"
#include "tests/certify/test_graphs.h"
#include "tests/data_paths.h"

namespace certislam::certify {
namespace {

constexpr double kLambdaTolerance = 1e-8;  ///< |distributed - centralised| / ||Q||
constexpr double kTraceTolerance = 1e-9;   ///< relative, sum of tr(Lambda) over robots

std::vector<CertificateRows> AllRows(const Eigen::SparseMatrix<double>& Q, const Eigen::MatrixXd& X,
                                     int d, const slam::Partition& partition) {
    std::vector<CertificateRows> rows;
    for (int k = 0; k < partition.num_robots(); ++k) {
        rows.push_back(MakeCertificateRows(Q, X, d, partition, k));
    }
    return rows;
}

TEST(DistributedCertificate, RowsReassembleTheCentralisedS) {
    const auto read = slam::ReadG2o(test_data::G2oPath("tinyGrid3D.g2o"));
    ASSERT_TRUE(read.ok()) << read.error;
    const int d = 3;
    const Eigen::SparseMatrix<double> Q = slam::ConnectionLaplacian(read.graph);
    const Eigen::MatrixXd X = slam::LiftToRank(slam::ChordalInitialization(read.graph), 5);
    const Eigen::MatrixXd S = Eigen::MatrixXd(CertificateMatrix(Q, LambdaBlocks(Q, X, d), d));
    const slam::Partition partition = slam::ContiguousPartition(read.graph.n, 3);
    const auto rows = AllRows(Q, X, d, partition);
    Eigen::MatrixXd assembled = Eigen::MatrixXd::Zero(S.rows(), S.cols());
    for (const auto& r : rows) {
        const int c0 = (d + 1) * r.first_pose;
        assembled.block(c0, c0, r.own.rows(), r.own.cols()) = Eigen::MatrixXd(r.own);
        const Eigen::MatrixXd nbr(r.nbr);
        for (size_t p = 0; p < r.neighbor_poses.size(); ++p) {
            assembled.block(c0, (d + 1) * r.neighbor_poses[p], r.own.rows(), d + 1) =
                nbr.middleCols((d + 1) * p, d + 1);
        }
    }
    EXPECT_LE((assembled - S).cwiseAbs().maxCoeff(), 1e-12 * S.cwiseAbs().maxCoeff());
}

TEST(DistributedCertificate, MatchesCentralisedLambdaMinAtCertifiedOptimum) {
    const auto read = slam::ReadG2o(test_data::G2oPath("smallGrid3D.g2o"));
    ASSERT_TRUE(read.ok()) << read.error;
    const slam::PoseGraph& graph = read.graph;
    const int d = graph.d;
    const slam::Partition partition = slam::ContiguousPartition(graph.n, 5);
    const StaircaseResult solved =
        SolveCertified(graph, partition, slam::LiftToRank(slam::ChordalInitialization(graph), d));
    ASSERT_EQ(solved.status, StaircaseResult::Status::kCertified);
    const Eigen::SparseMatrix<double> Q = slam::ConnectionLaplacian(graph);
    const auto rows = AllRows(Q, solved.X, d, partition);
    double trace = 0.0;
    for (const auto& r : rows) trace += r.trace_lambda;
    EXPECT_NEAR(trace, solved.certificate.dual_value, kTraceTolerance * std::abs(trace));
    LanczosSettings config;
    config.max_krylov = static_cast<int>(Q.rows());
    const DistributedEigenResult eig = DistributedMinEigenpair(rows, config);
    EXPECT_EQ(eig.status, DistributedEigenResult::Status::kConverged);
    const double q_norm = solved.certificate.q_norm;
    EXPECT_NEAR(eig.lambda_min, solved.certificate.lambda_min, kLambdaTolerance * q_norm)
        << "distributed " << eig.lambda_min << " centralised " << solved.certificate.lambda_min;
    EXPECT_GT(eig.products, 0);
    EXPECT_GT(eig.entries_exchanged, 0.0);
    // Each exchange sends exactly the entries of public poses (poses with a cross edge); the
    // message-driven Lanczos sends step k + 1's entries with step k's sums, so the last step may
    // send one vector that no product uses.
    double public_entries = 0.0;
    for (const auto& r : rows) public_entries += (d + 1.0) * r.public_poses.size();
    EXPECT_DOUBLE_EQ(eig.entries_exchanged, public_entries * eig.vector_exchanges);
    EXPECT_GE(eig.vector_exchanges, eig.products);
    EXPECT_LE(eig.vector_exchanges, eig.products + 1);
}

TEST(DistributedCertificate, FindsTheNegativeEigenvalueOfASaddle) {
    const int d = 3;
    const int n = 8;
    const slam::PoseGraph graph = testing::IdentityCycle(d, n);
    const Eigen::MatrixXd twisted = testing::TwistedCycle(d, n);
    const Eigen::SparseMatrix<double> Q = slam::ConnectionLaplacian(graph);
    const CertificateResult central = Certify(Q, twisted, d);
    ASSERT_EQ(central.status, CertificateResult::Status::kNotOptimal);
    ASSERT_LT(central.lambda_min, 0.0);
    const auto rows = AllRows(Q, twisted, d, slam::ContiguousPartition(n, 4));
    const DistributedEigenResult eig = DistributedMinEigenpair(rows);
    EXPECT_EQ(eig.status, DistributedEigenResult::Status::kConverged);
    EXPECT_NEAR(eig.lambda_min, central.lambda_min, kLambdaTolerance * central.q_norm);
    EXPECT_LT(eig.residual, 1e-6 * central.q_norm);
}

}  // namespace
}  // namespace certislam::certify
