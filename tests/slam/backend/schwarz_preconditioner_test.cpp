// The overlapping Schwarz preconditioner of RBCD's multi-robot finish, on real g2o files: its
// overlap-0 form is block Jacobi, its overlap-2 form equals a dense reference built from the
// edges and is symmetric positive definite, its domains are what the overlap says, it escalates
// when told of a long CG run, and on parking-garage it makes conjugate gradients converge where
// block Jacobi does not.
#include "slam/backend/schwarz_preconditioner.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <cstdio>
#include <random>
#include <set>
#include <string>

#include "slam/backend/connection_laplacian.h"
#include "slam/core/partition.h"
#include "slam/io/g2o_io.h"
#include "tests/data_paths.h"

namespace certislam::slam {
namespace {

constexpr double kRegulariser = 1e-8;  // as RbcdConfig::precon_regulariser
constexpr double kSolveTol = 1e-9;     // relative, factorisations of the same matrix
constexpr int kNeverEscalate = 1 << 30;

PoseGraphReadResult Read(const std::string& file) { return ReadG2o(test_data::G2oPath(file)); }

// Poses within `overlap` edges of robot k's own poses, from the edge list (independent of the
// preconditioner's adjacency built from Q).
std::set<int> DomainFromEdges(const PoseGraph& graph, const Partition& partition, int k,
                              int overlap) {
    std::set<int> domain;
    for (int i = partition.begin[k]; i < partition.begin[k + 1]; ++i) domain.insert(i);
    for (int level = 0; level < overlap; ++level) {
        std::set<int> grown = domain;
        for (const auto& e : graph.edges) {
            if (domain.count(e.i) > 0) grown.insert(e.j);
            if (domain.count(e.j) > 0) grown.insert(e.i);
        }
        domain = std::move(grown);
    }
    return domain;
}

Eigen::MatrixXd RandomMatrix(int rows, int cols, unsigned seed) {
    std::mt19937 rng(seed);
    std::normal_distribution<double> normal;
    Eigen::MatrixXd M(rows, cols);
    for (int i = 0; i < M.size(); ++i) M.data()[i] = normal(rng);
    return M;
}

double Shift(const Eigen::SparseMatrix<double>& Q) {
    return kRegulariser * Q.diagonal().maxCoeff();
}

TEST(SchwarzPreconditioner, OverlapZeroIsBlockJacobi) {
    const PoseGraphReadResult read = Read("smallGrid3D.g2o");
    ASSERT_TRUE(read.ok()) << read.error;
    const PoseGraph& graph = read.graph;
    const Eigen::SparseMatrix<double> Q = ConnectionLaplacian(graph);
    const Partition partition = ContiguousPartition(graph.n, 3);
    const SchwarzPreconditioner schwarz(Q, graph.d, partition, 0, kNeverEscalate, kRegulariser);
    EXPECT_EQ(schwarz.IterationCap(100), 100) << "no escalation possible";
    const Eigen::MatrixXd B = RandomMatrix(static_cast<int>(Q.rows()), 3, 1);
    const Eigen::MatrixXd Z = schwarz.Solve(B);
    const int b = graph.d + 1;
    for (int k = 0; k < partition.num_robots(); ++k) {
        const int c0 = b * partition.begin[k];
        const int m = b * partition.size(k);
        Eigen::SparseMatrix<double> Qkk = Q.block(c0, c0, m, m);
        for (int i = 0; i < m; ++i) Qkk.coeffRef(i, i) += Shift(Q);
        const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(Qkk);
        ASSERT_EQ(ldlt.info(), Eigen::Success);
        const Eigen::MatrixXd expected = ldlt.solve(B.middleRows(c0, m));
        EXPECT_LE((Z.middleRows(c0, m) - expected).norm(), kSolveTol * expected.norm())
            << "robot " << k;
    }
}

TEST(SchwarzPreconditioner, DomainsHoldThePosesWithinTheOverlap) {
    const PoseGraphReadResult read = Read("intel.g2o");
    ASSERT_TRUE(read.ok()) << read.error;
    const PoseGraph& graph = read.graph;
    const Eigen::SparseMatrix<double> Q = ConnectionLaplacian(graph);
    const Partition partition = ContiguousPartition(graph.n, 4);
    for (int overlap : {1, 2}) {
        SchwarzPreconditioner schwarz(Q, graph.d, partition, overlap, 10, kRegulariser);
        ASSERT_EQ(schwarz.overlap(), 0);
        EXPECT_EQ(schwarz.IterationCap(100), 11) << "a run is cut where it would escalate";
        schwarz.ReportCgIterations(10);  // not more than the threshold: stays block Jacobi
        EXPECT_EQ(schwarz.overlap(), 0);
        schwarz.ReportCgIterations(11);
        ASSERT_EQ(schwarz.overlap(), overlap);
        EXPECT_EQ(schwarz.IterationCap(100), 100);
        for (int k = 0; k < partition.num_robots(); ++k) {
            const std::vector<int>& domain = schwarz.Domain(k);
            EXPECT_EQ(std::set<int>(domain.begin(), domain.end()),
                      DomainFromEdges(graph, partition, k, overlap))
                << "robot " << k << ", overlap " << overlap;
            EXPECT_TRUE(std::is_sorted(domain.begin(), domain.end()));
            EXPECT_GT(domain.size(), static_cast<size_t>(partition.size(k))) << "robot " << k;
        }
    }
}

// P^{-1} as a dense matrix, against sum_k R_k^T (R_k Q_s R_k^T)^{-1} R_k built densely from
// domains taken from the edge list: checks the restriction's index mapping, then symmetry and
// positive definiteness of the whole operator.
TEST(SchwarzPreconditioner, OverlapTwoEqualsDenseReferenceAndIsPositiveDefinite) {
    constexpr double kDenseTol = 1e-9;  // relative, different factorisations of the same blocks
    const PoseGraphReadResult read = Read("smallGrid3D.g2o");
    ASSERT_TRUE(read.ok()) << read.error;
    const PoseGraph& graph = read.graph;
    const Eigen::SparseMatrix<double> Q = ConnectionLaplacian(graph);
    const Partition partition = ContiguousPartition(graph.n, 4);
    SchwarzPreconditioner schwarz(Q, graph.d, partition, 2, 1, kRegulariser);
    schwarz.ReportCgIterations(2);
    ASSERT_EQ(schwarz.overlap(), 2);
    const int N = static_cast<int>(Q.rows());
    const Eigen::MatrixXd P = schwarz.Solve(Eigen::MatrixXd::Identity(N, N));
    Eigen::MatrixXd Qs = Eigen::MatrixXd(Q);
    Qs.diagonal().array() += Shift(Q);
    const int b = graph.d + 1;
    Eigen::MatrixXd reference = Eigen::MatrixXd::Zero(N, N);
    for (int k = 0; k < partition.num_robots(); ++k) {
        std::vector<int> entries;
        for (int pose : DomainFromEdges(graph, partition, k, 2)) {
            for (int a = 0; a < b; ++a) entries.push_back(b * pose + a);
        }
        const int m = static_cast<int>(entries.size());
        Eigen::MatrixXd local(m, m);
        for (int i = 0; i < m; ++i) {
            for (int j = 0; j < m; ++j) local(i, j) = Qs(entries[i], entries[j]);
        }
        const Eigen::MatrixXd inverse = local.ldlt().solve(Eigen::MatrixXd::Identity(m, m));
        for (int i = 0; i < m; ++i) {
            for (int j = 0; j < m; ++j) reference(entries[i], entries[j]) += inverse(i, j);
        }
    }
    EXPECT_LE((P - reference).norm(), kDenseTol * reference.norm());
    EXPECT_LE((P - P.transpose()).norm(), kDenseTol * P.norm());
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(0.5 * (P + P.transpose()));
    EXPECT_GT(eig.eigenvalues().minCoeff(), 0.0);
}

// Preconditioned CG on Q_s x = b from 0; iterations to a relative residual of tol, or -1.
int PcgIterations(const Eigen::SparseMatrix<double>& Qs, const SchwarzPreconditioner& precon,
                  const Eigen::VectorXd& rhs, double tol, int max_iterations) {
    Eigen::VectorXd r = rhs;
    Eigen::VectorXd z = precon.Solve(r);
    Eigen::VectorXd p = z;
    double rz = r.dot(z);
    for (int k = 1; k <= max_iterations; ++k) {
        const Eigen::VectorXd Qp = Qs * p;
        const double alpha = rz / p.dot(Qp);
        r -= alpha * Qp;
        if (r.norm() <= tol * rhs.norm()) return k;
        z = precon.Solve(r);
        const double rz_new = r.dot(z);
        p = z + (rz_new / rz) * p;
        rz = rz_new;
    }
    return -1;
}

// parking-garage, 5 robots: block Jacobi misses the stiff loop closures between robots and
// needs thousands of CG iterations to 1e-8; overlap 2 converges within the cap.
TEST(SchwarzPreconditioner, OverlapMakesConjugateGradientsConvergeOnParkingGarage) {
    constexpr double kTol = 1e-8;
    constexpr int kCap = 150;
    const PoseGraphReadResult read = Read("parking-garage.g2o");
    ASSERT_TRUE(read.ok()) << read.error;
    const PoseGraph& graph = read.graph;
    const Eigen::SparseMatrix<double> Q = ConnectionLaplacian(graph);
    Eigen::SparseMatrix<double> Qs = Q;
    for (int i = 0; i < Qs.rows(); ++i) Qs.coeffRef(i, i) += Shift(Q);
    const Partition partition = ContiguousPartition(graph.n, 5);
    const Eigen::VectorXd rhs = RandomMatrix(static_cast<int>(Q.rows()), 1, 4).col(0);
    SchwarzPreconditioner schwarz(Q, graph.d, partition, 2, 1, kRegulariser);
    EXPECT_EQ(PcgIterations(Qs, schwarz, rhs, kTol, kCap), -1) << "block Jacobi converged";
    schwarz.ReportCgIterations(2);
    ASSERT_EQ(schwarz.overlap(), 2);
    const int overlapping = PcgIterations(Qs, schwarz, rhs, kTol, kCap);
    EXPECT_GT(overlapping, 0) << "overlap 2 did not converge within " << kCap;
    std::printf("parking-garage, 5 robots: overlap 2 CG iterations %d (block Jacobi > %d)\n",
                overlapping, kCap);
}

}  // namespace
}  // namespace certislam::slam
