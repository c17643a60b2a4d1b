// Q_TT factorised once per block; every use is one sparse product and one k x k solve.
#include "slam/backend/translation_elimination.h"

#include <algorithm>
#include <cmath>

#include "slam/backend/sparse_product.h"
#include "slam/core/check.h"

namespace certislam::slam {

TranslationElimination::TranslationElimination(const Eigen::SparseMatrix<double>& Q, int d,
                                               bool anchor_gauge)
    : d_(d), k_(static_cast<int>(Q.cols()) / (d + 1)) {
    const int b = d + 1;
    CERTISLAM_CHECK(Q.rows() == Q.cols() && Q.cols() % b == 0);
    std::vector<Eigen::Triplet<double>> tt, rt;
    double trace = 0.0;
    for (int i = 0; i < k_; ++i) {
        for (Eigen::SparseMatrix<double>::InnerIterator it(Q, b * i + d); it; ++it) {
            const int row = static_cast<int>(it.row());
            if (row % b == d) {
                tt.emplace_back(row / b, i, it.value());
                if (row / b == i) trace += it.value();
            } else {
                rt.emplace_back(row, i, it.value());
            }
        }
    }
    // Decided by the caller from the structure (no neighbour: Q_TT is a Laplacian, Q_TT 1 = 0),
    // not from the values: tiny but non-zero inter-robot weights (GNC ramps) are not a gauge.
    if (anchor_gauge && k_ > 0) tt.emplace_back(0, 0, std::max(trace / k_, 1.0));
    Eigen::SparseMatrix<double> Q_TT(k_, k_);
    Q_TT.setFromTriplets(tt.begin(), tt.end());
    Q_RT_.resize(Q.rows(), k_);
    Q_RT_.setFromTriplets(rt.begin(), rt.end());
    factor_.cholmod().print = 0;
    factor_.setMode(Eigen::CholmodSimplicialLLt);
    factor_.compute(Q_TT);
    valid_ = factor_.info() == Eigen::Success;
}

void TranslationElimination::SolveInto(const Eigen::MatrixXd& B, Eigen::MatrixXd* X) const {
    const Eigen::MatrixXd Bt = B.transpose();  // column-major right-hand sides
    const Eigen::MatrixXd T = factor_.solve(Bt);
    const int b = d_ + 1;
    for (int i = 0; i < k_; ++i) X->col(b * i + d_) = -T.row(i).transpose();
}

void TranslationElimination::OptimizeTranslations(Eigen::MatrixXd* X,
                                                  const Eigen::MatrixXd* G) const {
    CERTISLAM_CHECK(X->cols() == Q_RT_.rows());
    Eigen::MatrixXd B =
        DenseTimesSparse(*X, Q_RT_);  // translation rows of Q_RT_ are zero: X_R Q_RT
    if (G != nullptr && G->size() > 0) {
        const int b = d_ + 1;
        for (int i = 0; i < k_; ++i) B.col(i) += G->col(b * i + d_);
    }
    SolveInto(B, X);
}

void TranslationElimination::Lift(Eigen::MatrixXd* V) const {
    CERTISLAM_CHECK(V->cols() == Q_RT_.rows());
    SolveInto(DenseTimesSparse(*V, Q_RT_), V);
}

void TranslationElimination::ZeroTranslations(Eigen::MatrixXd* V) const {
    const int b = d_ + 1;
    for (int i = 0; i < k_; ++i) V->col(b * i + d_).setZero();
}

}  // namespace certislam::slam
