// Rounding the lifted solution to SE(d): SE-Sync's centralised rule and dpgo's anchored rule.
#include "slam/backend/rounding.h"

#include <Eigen/Dense>

#include "slam/backend/chordal.h"
#include "slam/core/check.h"

namespace certislam::slam {

namespace {

// The nearest rotation by a fixed-size SVD for d = 2, 3 (every pose of every snapshot is
// rounded): no heap allocation, unlike the dynamic-size decomposition below.
template <int D>
Eigen::MatrixXd ProjectFixed(const Eigen::MatrixXd& M) {
    using Mat = Eigen::Matrix<double, D, D>;
    const Eigen::JacobiSVD<Mat> svd(Mat(M), Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Matrix<double, D, 1> s = Eigen::Matrix<double, D, 1>::Ones();
    if ((svd.matrixU() * svd.matrixV().transpose()).determinant() < 0) s(D - 1) = -1.0;
    return svd.matrixU() * s.asDiagonal() * svd.matrixV().transpose();
}

}  // namespace

Eigen::MatrixXd ProjectToRotation(const Eigen::MatrixXd& M) {
    const int d = static_cast<int>(M.rows());
    if (M.cols() == d && d == 3) return ProjectFixed<3>(M);
    if (M.cols() == d && d == 2) return ProjectFixed<2>(M);
    Eigen::JacobiSVD<Eigen::MatrixXd> svd(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::VectorXd s = Eigen::VectorXd::Ones(d);
    if ((svd.matrixU() * svd.matrixV().transpose()).determinant() < 0) s(d - 1) = -1.0;
    return svd.matrixU() * s.asDiagonal() * svd.matrixV().transpose();
}

PoseMatrix RoundSolution(const PoseGraph& graph, const Eigen::MatrixXd& X) {
    const int d = graph.d;
    const int n = graph.n;
    const int r = static_cast<int>(X.rows());
    CERTISLAM_CHECK(X.cols() == (d + 1) * n && r >= d);
    // Top-d left singular vectors of the rotation part Y (r x dn), from Y Y^T (r x r).
    Eigen::MatrixXd YYt = Eigen::MatrixXd::Zero(r, r);
    for (int g = 0; g < n; ++g) {
        const auto Y = X.middleCols(BlockColumn(g, d), d);
        YYt.noalias() += Y * Y.transpose();
    }
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(YYt);
    const Eigen::MatrixXd Ud = eig.eigenvectors().rightCols(d).rowwise().reverse();
    PoseMatrix poses = PoseMatrix::Zero(d, (d + 1) * n);
    int positive = 0;
    for (int g = 0; g < n; ++g) {
        poses.block(0, BlockColumn(g, d), d, d) =
            Ud.transpose() * X.middleCols(BlockColumn(g, d), d);
        if (poses.block(0, BlockColumn(g, d), d, d).determinant() > 0) ++positive;
    }
    if (positive < n - positive) {  // SE-Sync: reflect when most blocks have det < 0
        for (int g = 0; g < n; ++g) poses.row(d - 1).segment(BlockColumn(g, d), d) *= -1.0;
    }
    for (int g = 0; g < n; ++g) {
        poses.block(0, BlockColumn(g, d), d, d) =
            ProjectToRotation(poses.block(0, BlockColumn(g, d), d, d));
    }
    return RecoverTranslations(graph, poses);
}

PoseMatrix RoundWithAnchor(const Eigen::MatrixXd& X, int d, int anchor) {
    const int n = static_cast<int>(X.cols()) / (d + 1);
    CERTISLAM_CHECK(anchor >= 0 && anchor < n);
    const Eigen::MatrixXd Ya = X.middleCols(BlockColumn(anchor, d), d);
    PoseMatrix T = Ya.transpose() * X;
    const Eigen::VectorXd ta = T.col(BlockColumn(anchor, d) + d);
    for (int g = 0; g < n; ++g) {
        T.block(0, BlockColumn(g, d), d, d) =
            ProjectToRotation(T.block(0, BlockColumn(g, d), d, d));
        T.col(BlockColumn(g, d) + d) -= ta;
    }
    return T;
}

}  // namespace certislam::slam
