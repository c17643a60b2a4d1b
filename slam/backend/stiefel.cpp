// Per-pose St(d, r) x R^r operations on the lifted variable's layout (r x (d+1)k).
#include "slam/backend/stiefel.h"

#include <Eigen/Dense>
#include <cmath>

#include "slam/core/check.h"

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

// For every pose y: out_y += sign * L_y sym(A_y^T B_y), with A_y, B_y, L_y the r x D rotation
// blocks of A, B, L. Plain loops over the column-major storage: on r x D blocks of dynamic
// matrices Eigen's small products cost more in dispatch than in arithmetic; R = r fixed at
// compile time lets the compiler unroll them (R = 0: runtime r).
template <int D, int R>
void AddSymProducts(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::MatrixXd& L,
                    double sign, int k, Eigen::MatrixXd* out) {
    const Eigen::Index r = R > 0 ? R : A.rows();
    for (int g = 0; g < k; ++g) {
        const Eigen::Index offset = r * (D + 1) * g;
        const double* a = A.data() + offset;
        const double* b = B.data() + offset;
        double s[D][D];
        for (int i = 0; i < D; ++i) {
            for (int j = 0; j < D; ++j) {
                double acc = 0.0;
                for (Eigen::Index t = 0; t < r; ++t) acc += a[i * r + t] * b[j * r + t];
                s[i][j] = acc;
            }
        }
        const double* l = L.data() + offset;
        double* o = out->data() + offset;
        for (int j = 0; j < D; ++j) {
            for (int i = 0; i < D; ++i) {
                const double w = sign * 0.5 * (s[i][j] + s[j][i]);
                for (Eigen::Index t = 0; t < r; ++t) o[j * r + t] += l[i * r + t] * w;
            }
        }
    }
}

// AddSymProducts for the problem's dimension d (2 or 3, checked by PoseCount).
void AddSymProducts(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::MatrixXd& L,
                    double sign, int d, Eigen::MatrixXd* out) {
    const int k = PoseCount(A, d);
    CERTISLAM_CHECK(B.rows() == A.rows() && B.cols() == A.cols());
    CERTISLAM_CHECK(L.rows() == A.rows() && L.cols() == A.cols());
    const Eigen::Index r = A.rows();
    if (d == 2) {
        r == 2 ? AddSymProducts<2, 2>(A, B, L, sign, k, out)
               : AddSymProducts<2, 0>(A, B, L, sign, k, out);
    } else {
        r == 3 ? AddSymProducts<3, 3>(A, B, L, sign, k, out)
               : AddSymProducts<3, 0>(A, B, L, sign, k, out);
    }
}

}  // namespace

Eigen::MatrixXd ProjectToTangent(const Eigen::MatrixXd& X, const Eigen::MatrixXd& V, int d) {
    Eigen::MatrixXd out = V;
    AddSymProducts(X, V, X, -1.0, d, &out);
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
    Eigen::MatrixXd out = Eigen::MatrixXd::Zero(X.rows(), X.cols());
    AddSymProducts(X, G, V, 1.0, d, &out);
    return out;
}

}  // namespace certislam::slam
