// Exact elimination of a block's translations (SE-Sync's reduced problem, kept in the explicit
// layout): for fixed rotations the block cost tr(X Q X^T) + 2 <X, G> is quadratic in the
// translations, so the trust region works on the rotations alone with the Schur complement
// Q_RR - Q_RT Q_TT^{-1} Q_TR as its quadratic form.
#pragma once

#include <Eigen/CholmodSupport>
#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <vector>

namespace certislam::slam {

/// Translation columns T and rotation columns R of a block's Q ((d+1)k x (d+1)k, pose-major),
/// copied, with a sparse Cholesky of Q_TT (k x k, the translation Laplacian of the block; rebuild
/// the object if Q changes). A block with no neighbour (or a whole graph) has the translation
/// gauge as a null direction of Q_TT: the caller says so and the first translation is anchored
/// (any minimiser is as good: the cost does not change along the gauge; the returned X then has
/// its first translation at the optimum of the anchored problem, not in the input's gauge).
class TranslationElimination {
  public:
    /// d the dimension; anchor_gauge: Q_TT has the translation gauge as null direction (a
    /// block without neighbours). valid() is false when Q_TT still does not factorise (a
    /// block whose own graph falls apart): callers then keep the explicit problem.
    TranslationElimination(const Eigen::SparseMatrix<double>& Q, int d, bool anchor_gauge);

    /// Q_TT factorised: the elimination can be used.
    bool valid() const { return valid_; }

    /// Sets X's translation columns to their optimum for its rotation columns:
    /// X_T = -(X_R Q_RT + G_T) Q_TT^{-1}; G null or empty: no linear term.
    void OptimizeTranslations(Eigen::MatrixXd* X, const Eigen::MatrixXd* G) const;

    /// Sets V's translation columns to the optimum's first-order response to V's rotation
    /// columns, V_T = -V_R Q_RT Q_TT^{-1}: then V Q has zero translation columns and its
    /// rotation columns are V_R (Q_RR - Q_RT Q_TT^{-1} Q_TR).
    void Lift(Eigen::MatrixXd* V) const;

    /// Sets V's translation columns to zero.
    void ZeroTranslations(Eigen::MatrixXd* V) const;

  private:
    // -(B Q_TT^{-1}) written into the translation columns of *X, B = r x k.
    void SolveInto(const Eigen::MatrixXd& B, Eigen::MatrixXd* X) const;

    int d_;
    int k_;
    bool valid_ = false;
    Eigen::SparseMatrix<double>
        Q_RT_;  // (d+1)k x k: Q's translation columns, translation rows zeroed
    Eigen::CholmodDecomposition<Eigen::SparseMatrix<double>, Eigen::Lower> factor_;  // of Q_TT
};

}  // namespace certislam::slam
