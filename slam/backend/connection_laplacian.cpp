// Connection Laplacian assembly and the objective evaluated edge by edge.
#include "slam/backend/connection_laplacian.h"

#include <Eigen/Dense>
#include <vector>

#include "slam/core/check.h"

namespace certislam::slam {

Eigen::SparseMatrix<double> ConnectionLaplacian(const PoseGraph& graph) {
    const int d = graph.d;
    const int b = d + 1;
    const int size = b * graph.n;
    std::vector<Eigen::Triplet<double>> triplets;
    triplets.reserve(graph.edges.size() * 4 * b * b);
    Eigen::MatrixXd T = Eigen::MatrixXd::Identity(b, b);
    Eigen::MatrixXd omega = Eigen::MatrixXd::Zero(b, b);
    for (const auto& e : graph.edges) {
        CERTISLAM_CHECK(e.i >= 0 && e.i < graph.n && e.j >= 0 && e.j < graph.n);
        T.topLeftCorner(d, d) = e.R;
        T.topRightCorner(d, 1) = e.t;
        omega.setZero();
        omega.diagonal().head(d).setConstant(e.weight * e.kappa);
        omega(d, d) = e.weight * e.tau;
        // SE-Sync's L(G~rho) puts kappa I on the tail's rotation block (not kappa R~ R~^T): the
        // file's rotations are not exactly orthogonal (quaternions are not renormalised), and
        // the reference optima f* are tr(X Q X^T) for this Q.
        Eigen::MatrixXd ii = T * omega * T.transpose();
        ii.topLeftCorner(d, d) +=
            e.weight * e.kappa * (Eigen::MatrixXd::Identity(d, d) - e.R * e.R.transpose());
        const Eigen::MatrixXd ij = -T * omega;
        const int ci = BlockColumn(e.i, d);
        const int cj = BlockColumn(e.j, d);
        for (int r = 0; r < b; ++r) {
            for (int c = 0; c < b; ++c) {
                triplets.emplace_back(ci + r, ci + c, ii(r, c));
                triplets.emplace_back(cj + r, cj + c, omega(r, c));
                triplets.emplace_back(ci + r, cj + c, ij(r, c));
                triplets.emplace_back(cj + c, ci + r, ij(r, c));
            }
        }
    }
    Eigen::SparseMatrix<double> Q(size, size);
    Q.setFromTriplets(triplets.begin(), triplets.end());
    Q.prune(0.0);
    return Q;
}

double Objective(const PoseGraph& graph, const PoseMatrix& poses) {
    const int d = graph.d;
    double f = 0.0;
    for (const auto& e : graph.edges) {
        const auto Ri = poses.block(0, BlockColumn(e.i, d), d, d);
        const auto ti = poses.col(BlockColumn(e.i, d) + d);
        const auto Rj = poses.block(0, BlockColumn(e.j, d), d, d);
        const auto tj = poses.col(BlockColumn(e.j, d) + d);
        // ||R_j - R_i R~||^2 with ||R_i R~||^2 taken as ||R_i||^2 (= d for a rotation), as
        // SE-Sync's Q does: identical when R~ is orthogonal, and the f* convention otherwise.
        // Written as the square plus ||R_i||^2 - ||R_i R~||^2 = <R_i^T R_i, I - R~ R~^T>, so no
        // term of size ||R||^2 cancels (on an f* = 0 graph the cancelled form can go negative).
        const Eigen::MatrixXd RiRt = Ri * e.R;
        const Eigen::MatrixXd defect = Eigen::MatrixXd::Identity(d, d) - e.R * e.R.transpose();
        const double rot =
            (Rj - RiRt).squaredNorm() + (Ri.transpose() * Ri).cwiseProduct(defect).sum();
        f += e.weight * (e.kappa * rot + e.tau * (tj - ti - Ri * e.t).squaredNorm());
    }
    return f;
}

}  // namespace certislam::slam
