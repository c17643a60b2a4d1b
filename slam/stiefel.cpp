// Per-pose St(d, r) x R^r operations on the lifted variable's layout (r x (d+1)k).
#include "slam/stiefel.h"

#include <Eigen/Dense>
#include <cmath>

#include "slam/check.h"

namespace certislam::slam {
namespace {

// d x d matrices with d <= 3: no heap allocation in the per-pose loops.
using Small = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 3, 3>;

int PoseCount(const Eigen::MatrixXd& X, int d) {
    CERTISLAM_CHECK(d == 2 || d == 3);
    CERTISLAM_CHECK(X.cols() % (d + 1) == 0);
    return static_cast<int>(X.cols()) / (d + 1);
}

// Polar factor A (A^T A)^{-1/2} of the r x d block A, written into out.
template <typename In, typename Out>
void PolarFactor(const In& A, Out out, int d) {
    const Small AtA = A.transpose() * A;
    Eigen::SelfAdjointEigenSolver<Small> eig(AtA);
    Small inv_sqrt = Small::Zero(d, d);
    const auto& lambda = eig.eigenvalues();
    const double floor = 1e-300;
    for (int k = 0; k < d; ++k) {
        const double l = std::max(lambda(k), floor);
        inv_sqrt.noalias() += (1.0 / std::sqrt(l)) * eig.eigenvectors().col(k) *
                              eig.eigenvectors().col(k).transpose();
    }
    out.noalias() = A * inv_sqrt;
}

}  // namespace

Eigen::MatrixXd ProjectToTangent(const Eigen::MatrixXd& X, const Eigen::MatrixXd& V, int d) {
    const int k = PoseCount(X, d);
    Eigen::MatrixXd out = V;
    for (int g = 0; g < k; ++g) {
        const int c = g * (d + 1);
        const auto Y = X.middleCols(c, d);
        const Small S = Y.transpose() * V.middleCols(c, d);
        const Small sym = 0.5 * (S + S.transpose());
        out.middleCols(c, d).noalias() -= Y * sym;
    }
    return out;
}

Eigen::MatrixXd Retract(const Eigen::MatrixXd& X, const Eigen::MatrixXd& V, int d) {
    return ProjectToManifold(X + V, d);
}

Eigen::MatrixXd ProjectToManifold(const Eigen::MatrixXd& X, int d) {
    const int k = PoseCount(X, d);
    Eigen::MatrixXd out = X;
    Eigen::MatrixXd A(X.rows(), d);
    for (int g = 0; g < k; ++g) {
        const int c = g * (d + 1);
        A = X.middleCols(c, d);
        PolarFactor(A, out.middleCols(c, d), d);
    }
    return out;
}

Eigen::MatrixXd WeingartenTerm(const Eigen::MatrixXd& X, const Eigen::MatrixXd& G,
                               const Eigen::MatrixXd& V, int d) {
    const int k = PoseCount(X, d);
    Eigen::MatrixXd out = Eigen::MatrixXd::Zero(X.rows(), X.cols());
    for (int g = 0; g < k; ++g) {
        const int c = g * (d + 1);
        const Small S = X.middleCols(c, d).transpose() * G.middleCols(c, d);
        const Small sym = 0.5 * (S + S.transpose());
        out.middleCols(c, d).noalias() = V.middleCols(c, d) * sym;
    }
    return out;
}

}  // namespace certislam::slam
