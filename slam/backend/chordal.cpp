// Chordal and odometry initialisation, optimal translations for fixed rotations, lifting.
#include "slam/backend/chordal.h"

#include <Eigen/Dense>
#include <Eigen/SparseCholesky>
#include <deque>
#include <random>
#include <vector>

#include "slam/backend/rounding.h"
#include "slam/core/check.h"

namespace certislam::slam {
namespace {

using Triplets = std::vector<Eigen::Triplet<double>>;

// Adds the d x d block B at block (bi, bj) of a matrix whose block 0 is eliminated (fixed):
// blocks are shifted by one and block 0 is skipped.
void AddReducedBlock(Triplets* t, int bi, int bj, const Eigen::MatrixXd& B) {
    if (bi == 0 || bj == 0) return;
    const int d = static_cast<int>(B.rows());
    for (int r = 0; r < d; ++r) {
        for (int c = 0; c < B.cols(); ++c) {
            t->emplace_back((bi - 1) * d + r, (bj - 1) * static_cast<int>(B.cols()) + c, B(r, c));
        }
    }
}

Eigen::MatrixXd SolveSpd(const Triplets& triplets, int size, const Eigen::MatrixXd& rhs) {
    Eigen::SparseMatrix<double> A(size, size);
    A.setFromTriplets(triplets.begin(), triplets.end());
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(A);
    CERTISLAM_CHECK(ldlt.info() == Eigen::Success);  // the readers reject disconnected graphs
    return ldlt.solve(rhs);
}

}  // namespace

PoseMatrix RecoverTranslations(const PoseGraph& graph, const PoseMatrix& poses) {
    const int d = graph.d;
    const int n = graph.n;
    PoseMatrix out = poses;
    for (int g = 0; g < n; ++g) out.col(BlockColumn(g, d) + d).setZero();
    if (n < 2) return out;
    // Normal equations L t^T = B of sum tau ||t_j - t_i - R_i t~||^2 with t_0 = 0 eliminated.
    Triplets triplets;
    Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(n - 1, d);
    Eigen::MatrixXd one(1, 1);
    for (const auto& e : graph.edges) {
        const Eigen::VectorXd c = poses.block(0, BlockColumn(e.i, d), d, d) * e.t;
        const double w = e.weight * e.tau;
        one(0, 0) = w;
        AddReducedBlock(&triplets, e.i, e.i, one);
        AddReducedBlock(&triplets, e.j, e.j, one);
        one(0, 0) = -w;
        AddReducedBlock(&triplets, e.i, e.j, one);
        AddReducedBlock(&triplets, e.j, e.i, one);
        if (e.j > 0) rhs.row(e.j - 1) += w * c.transpose();
        if (e.i > 0) rhs.row(e.i - 1) -= w * c.transpose();
    }
    const Eigen::MatrixXd t = SolveSpd(triplets, n - 1, rhs);
    for (int g = 1; g < n; ++g) out.col(BlockColumn(g, d) + d) = t.row(g - 1).transpose();
    return out;
}

PoseMatrix ChordalInitialization(const PoseGraph& graph) {
    const int d = graph.d;
    const int n = graph.n;
    PoseMatrix poses = PoseMatrix::Zero(d, (d + 1) * n);
    poses.block(0, 0, d, d).setIdentity();
    if (n >= 2) {
        // sum kappa ||R_j - R_i R~||^2 = tr(R M R^T); with R_0 = I: M_rr R_r^T = -M_r0.
        Triplets triplets;
        Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(d * (n - 1), d);
        const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(d, d);
        for (const auto& e : graph.edges) {
            const double k = e.weight * e.kappa;
            AddReducedBlock(&triplets, e.j, e.j, k * I);
            AddReducedBlock(&triplets, e.i, e.i, k * e.R * e.R.transpose());
            AddReducedBlock(&triplets, e.i, e.j, -k * e.R);
            AddReducedBlock(&triplets, e.j, e.i, -k * e.R.transpose());
            if (e.i == 0 && e.j > 0) rhs.middleRows(d * (e.j - 1), d) += k * e.R.transpose();
            if (e.j == 0 && e.i > 0) rhs.middleRows(d * (e.i - 1), d) += k * e.R;
        }
        const Eigen::MatrixXd Rt = SolveSpd(triplets, d * (n - 1), rhs);
        for (int g = 1; g < n; ++g) {
            poses.block(0, BlockColumn(g, d), d, d) =
                ProjectToRotation(Rt.middleRows(d * (g - 1), d).transpose());
        }
    }
    return RecoverTranslations(graph, poses);
}

PoseMatrix OdometryInitialization(const PoseGraph& graph) {
    const int d = graph.d;
    const int n = graph.n;
    std::vector<std::vector<int>> adjacent(n);
    for (int pass = 0; pass < 2; ++pass) {  // odometry edges first
        for (int k = 0; k < static_cast<int>(graph.edges.size()); ++k) {
            const auto& e = graph.edges[k];
            if ((std::abs(e.i - e.j) == 1) != (pass == 0)) continue;
            adjacent[e.i].push_back(k);
            adjacent[e.j].push_back(k);
        }
    }
    PoseMatrix poses = PoseMatrix::Zero(d, (d + 1) * n);
    poses.block(0, 0, d, d).setIdentity();
    std::vector<bool> known(n, false);
    known[0] = true;
    std::deque<int> queue{0};
    while (!queue.empty()) {
        const int a = queue.front();
        queue.pop_front();
        for (int k : adjacent[a]) {
            const auto& e = graph.edges[k];
            const int b = e.i == a ? e.j : e.i;
            if (known[b]) continue;
            const Eigen::MatrixXd Rm = ProjectToRotation(e.R);
            const Eigen::MatrixXd Ra = poses.block(0, BlockColumn(a, d), d, d);
            const Eigen::VectorXd ta = poses.col(BlockColumn(a, d) + d);
            Eigen::MatrixXd Rb =
                e.i == a ? Eigen::MatrixXd(Ra * Rm) : Eigen::MatrixXd(Ra * Rm.transpose());
            Eigen::VectorXd tb =
                e.i == a ? Eigen::VectorXd(ta + Ra * e.t) : Eigen::VectorXd(ta - Rb * e.t);
            poses.block(0, BlockColumn(b, d), d, d) = Rb;
            poses.col(BlockColumn(b, d) + d) = tb;
            known[b] = true;
            queue.push_back(b);
        }
    }
    return poses;
}

Eigen::MatrixXd LiftToRank(const PoseMatrix& poses, int r, std::uint64_t seed) {
    const int d = static_cast<int>(poses.rows());
    CERTISLAM_CHECK(r >= d);
    if (r == d) return poses;
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> gauss;
    Eigen::MatrixXd G(r, d);
    for (int i = 0; i < r; ++i) {
        for (int j = 0; j < d; ++j) G(i, j) = gauss(rng);
    }
    const Eigen::MatrixXd U =
        Eigen::HouseholderQR<Eigen::MatrixXd>(G).householderQ() * Eigen::MatrixXd::Identity(r, d);
    return U * poses;
}

}  // namespace certislam::slam
