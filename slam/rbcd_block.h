// The block solver of RBCD: preconditioned Riemannian trust region (Steihaug-CG, exact Hessian)
// on one robot's block, min tr(X Q X^T) + 2 <X, G> over the product of St(d, r) x R^r.
#pragma once

#include <Eigen/CholmodSupport>
#include <Eigen/Core>
#include <Eigen/SparseCore>

namespace certislam::slam {

/// Sparse Cholesky of Q_aa + lambda I, factorised once per block, used as preconditioner.
/// CHOLMOD's supernodal LL^T: its BLAS triangular solves on the r right-hand sides are several
/// times faster than Eigen's simplicial ones, which dominated the solve time.
using BlockFactor = Eigen::CholmodDecomposition<Eigen::SparseMatrix<double>, Eigen::Lower>;

/// One block's quadratic problem; pointers are borrowed for the duration of a solve.
struct BlockProblem {
    const Eigen::SparseMatrix<double>* Q = nullptr;  ///< Q_aa, (d+1)k x (d+1)k
    const Eigen::MatrixXd* G = nullptr;              ///< linear term r x (d+1)k (zero: none)
    const BlockFactor* precon = nullptr;             ///< factor of Q_aa + lambda I
    int d = 3;                                       ///< dimension
};

/// Settings of one block solve.
struct BlockRtrOptions {
    int max_iterations = 5;        ///< trust-region steps, >= 1
    int max_tcg_iterations = 100;  ///< Steihaug-CG iterations per step, >= 1
    double grad_tol = 0.0;         ///< stop when ||rgrad|| <= this
    double grad_reduction = 1e-2;  ///< or when ||rgrad|| <= this * initial ||rgrad||
};

/// What a block solve did.
struct BlockRtrOutcome {
    double cost_before = 0.0;       ///< block cost at the start
    double cost_after = 0.0;        ///< block cost at the end
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
