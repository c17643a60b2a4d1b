// The block solver of RBCD: preconditioned Riemannian trust region (Steihaug-CG, exact Hessian)
// on one robot's block, min tr(X Q X^T) + 2 <X, G> over the product of St(d, r) x R^r.
#pragma once

#include <Eigen/CholmodSupport>
#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <vector>

#include "slam/backend/translation_elimination.h"

namespace certislam::slam {

class SchwarzPreconditioner;

/// Sparse Cholesky of Q_aa + lambda I, factorised once per block, used as preconditioner.
/// CHOLMOD: its solves dominate the solve time. Factors solved hundreds of times on r right-hand
/// sides use its simplicial mode: with Debian's ATLAS (reference trsm) supernodal solves, and
/// Eigen's simplicial ones, are slower on these sparse factors.
using BlockFactor = Eigen::CholmodDecomposition<Eigen::SparseMatrix<double>, Eigen::Lower>;

/// Sparse Cholesky of the matrix of the block's exact Riemannian Hessian,
/// S_aa(X) = Q_aa - blockdiag(Lambda_a(X)) + mu D (D: identity on rotation entries, plus an
/// anchor on the first translation entry for the translation gauge), refactorised (numeric
/// only; one symbolic analysis) at every trust-region iterate. The Hessian is 2 Proj(V S_aa):
/// Q_aa alone misses the Lambda term, so truncated CG runs to its cap on ill-conditioned graphs
/// (parking-garage); S_aa makes tCG nearly exact in a few iterations.
/// mu starts at min_shift * max diag(Q_aa) and grows by 100x while the factorization fails (S
/// indefinite away from an optimum); after max_attempts failures the caller falls back to Q_aa.
class HessianPreconditioner {
  public:
    /// Q is the block's Q_aa (borrowed for the object's lifetime); d the dimension.
    HessianPreconditioner(const Eigen::SparseMatrix<double>& Q, int d);
    /// Factorises S_aa at X with egrad = 2 (X Q_aa + G); false when no shift up to the last
    /// attempt gave a positive definite matrix (then valid() is false too).
    bool Refactor(const Eigen::MatrixXd& X, const Eigen::MatrixXd& egrad);
    /// True after a successful Refactor.
    bool valid() const { return valid_; }
    /// The factor of the last successful Refactor.
    const BlockFactor& factor() const { return factor_; }
    /// (S_aa + mu D)^{-1} B for B of (d+1)k rows.
    Eigen::MatrixXd Solve(const Eigen::MatrixXd& B) const;
    /// Numeric factorizations done (for profiling).
    int factorizations() const { return factorizations_; }

    double min_shift = 1e-9;  ///< first mu relative to max diag(Q_aa), > 0
    int max_attempts = 4;     ///< factorizations tried per Refactor, >= 1

  private:
    const Eigen::SparseMatrix<double>* Q_;
    int d_;
    double scale_ = 1.0;                // max diag(Q_aa)
    Eigen::SparseMatrix<double> base_;  // Q_aa with explicit d x d diagonal blocks, anchored
    std::vector<int> block_index_;      // valuePtr index of each rotation block entry (i, a, b)
    std::vector<int> diag_index_;       // valuePtr index of each rotation diagonal entry
    BlockFactor factor_;
    bool valid_ = false;
    double last_shift_ = 0.0;
    int factorizations_ = 0;
};

/// One block's quadratic problem; pointers are borrowed for the duration of a solve.
struct BlockProblem {
    const Eigen::SparseMatrix<double>* Q = nullptr;  ///< Q_aa, (d+1)k x (d+1)k
    const Eigen::MatrixXd* G = nullptr;              ///< linear term r x (d+1)k (zero: none)
    const BlockFactor* precon = nullptr;             ///< factor of Q_aa + lambda I (or schwarz)
    int d = 3;                                       ///< dimension
    /// Optional Hessian preconditioner (refactorised at each iterate); null: `precon` only.
    HessianPreconditioner* hessian = nullptr;
    /// Optional exact elimination of the translations: the trust region then runs on the
    /// rotations alone (tangent vectors have zero translation columns) and every iterate has
    /// optimal translations; null: the explicit problem over rotations and translations.
    const TranslationElimination* elim = nullptr;
    /// Optional overlapping Schwarz preconditioner (the multi-robot finish), used instead of
    /// `precon` and `hessian`; told each truncated CG's iteration count (it may escalate).
    SchwarzPreconditioner* schwarz = nullptr;
};

/// Settings of one block solve.
struct BlockRtrOptions {
    int max_iterations = 5;        ///< trust-region steps, >= 1
    int max_tcg_iterations = 100;  ///< Steihaug-CG iterations per step, >= 1
    /// CG stops at the latest at residual <= this * the gradient tolerance (0: Manopt's rule)
    double tcg_residual_floor = 0.0;
    double grad_tol = 0.0;         ///< stop when ||rgrad|| <= this
    double grad_reduction = 1e-2;  ///< or when ||rgrad|| <= this * initial ||rgrad||
};

/// What a block solve did.
struct BlockRtrOutcome {
    double cost_before = 0.0;  ///< block cost at the start (after translation elimination, if on)
    double cost_after = 0.0;   ///< block cost at the end
    double grad_norm_before = 0.0;  ///< ||rgrad|| at the start
    double grad_norm_after = 0.0;   ///< ||rgrad|| at the end
    int iterations = 0;             ///< trust-region steps tried
    int accepted = 0;               ///< trust-region steps accepted
};

/// Block cost tr(X Q X^T) + 2 <X, G>.
double BlockCost(const BlockProblem& problem, const Eigen::MatrixXd& X);

/// Riemannian gradient norm of the block cost at X.
double BlockGradNorm(const BlockProblem& problem, const Eigen::MatrixXd& X);

/// Runs the trust-region method from *X (a point of the manifold) and leaves the result there.
BlockRtrOutcome SolveBlockRtr(const BlockProblem& problem, const BlockRtrOptions& options,
                              Eigen::MatrixXd* X);

}  // namespace certislam::slam
