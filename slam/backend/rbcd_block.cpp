// Riemannian trust region with truncated (Steihaug-Toint) preconditioned CG, as in Absil et al.
// "Trust-region methods on Riemannian manifolds" (2007) and Manopt's trustregions/tCG; the
// Hessian is exact: Proj(2 V Q - V sym(Y^T egrad)) on rotation blocks (Weingarten term).
#include "slam/backend/rbcd_block.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>

#include "slam/backend/schwarz_preconditioner.h"
#include "slam/backend/sparse_product.h"
#include "slam/backend/stiefel.h"
#include "slam/core/check.h"

namespace certislam::slam {
namespace {

constexpr double kNoiseMultiple = 10.0;  ///< rho regularisation in units of the cost noise

double Inner(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B) { return A.cwiseProduct(B).sum(); }

Eigen::MatrixXd TimesQ(const Eigen::MatrixXd& V, const Eigen::SparseMatrix<double>& Q) {
    return DenseTimesSparse(V, Q);
}

// The state at one iterate: cost, Euclidean and Riemannian gradients.
struct Iterate {
    Eigen::MatrixXd X;
    Eigen::MatrixXd egrad;
    Eigen::MatrixXd rgrad;
    double cost = 0.0;
    double grad_norm = 0.0;
};

// translations_optimal: X already has its optimal translations (an accepted trial point), so
// the elimination's solve is not repeated.
Iterate Evaluate(const BlockProblem& p, Eigen::MatrixXd X, bool translations_optimal = false) {
    if (p.elim != nullptr && !translations_optimal) p.elim->OptimizeTranslations(&X, p.G);
    Iterate it;
    it.egrad = TimesQ(X, *p.Q);
    it.cost = Inner(it.egrad, X);
    if (p.G && p.G->size() > 0) {
        it.cost += 2.0 * Inner(X, *p.G);
        it.egrad += *p.G;
    }
    it.egrad *= 2.0;
    it.rgrad = ProjectToTangent(X, it.egrad, p.d);
    if (p.elim != nullptr) p.elim->ZeroTranslations(&it.rgrad);  // ~0 at optimal translations
    it.grad_norm = it.rgrad.norm();
    it.X = std::move(X);
    return it;
}

double CostOnly(const BlockProblem& p, const Eigen::MatrixXd& X) {
    double f = Inner(TimesQ(X, *p.Q), X);
    if (p.G && p.G->size() > 0) f += 2.0 * Inner(X, *p.G);
    return f;
}

// f(X_new) - f(X) = <D Q, X_new + X> + 2 <D, G> with D = X_new - X, and its rounding noise.
// Subtracting two costs loses everything on metric-scale maps with a small f (parking-garage):
// tr(X Q X^T) sums terms far larger than f, so near the optimum the difference of two
// evaluations is rounding noise larger than the model decrease, and every step is rejected.
struct CostChange {
    double value = 0.0;
    double noise = 0.0;
};

CostChange CostDifference(const BlockProblem& p, const Eigen::MatrixXd& X,
                          const Eigen::MatrixXd& X_new) {
    const Eigen::MatrixXd D = X_new - X;
    const Eigen::MatrixXd DQ = TimesQ(D, *p.Q);
    const Eigen::MatrixXd sum = X_new + X;
    CostChange c;
    c.value = Inner(DQ, sum);
    if (p.G && p.G->size() > 0) c.value += 2.0 * Inner(D, *p.G);
    c.noise = std::numeric_limits<double>::epsilon() * DQ.norm() * sum.norm();
    return c;
}

int ValueIndex(const Eigen::SparseMatrix<double>& M, int row, int col) {
    const int* inner = M.innerIndexPtr();
    const int* begin = inner + M.outerIndexPtr()[col];
    const int* end = inner + M.outerIndexPtr()[col + 1];
    const int* it = std::lower_bound(begin, end, row);
    CERTISLAM_CHECK(it != end && *it == row);
    return static_cast<int>(it - inner);
}

Eigen::MatrixXd Hessian(const BlockProblem& p, const Iterate& it, const Eigen::MatrixXd& V) {
    Eigen::MatrixXd H;
    if (p.elim != nullptr) {  // the reduced Hessian: V's translations follow its rotations
        Eigen::MatrixXd lifted = V;
        p.elim->Lift(&lifted);
        H = 2.0 * TimesQ(lifted, *p.Q);
        p.elim->ZeroTranslations(&H);
    } else {
        H = 2.0 * TimesQ(V, *p.Q);
    }
    H -= WeingartenTerm(it.X, it.egrad, V, p.d);
    return ProjectToTangent(it.X, H, p.d);
}

Eigen::MatrixXd Precondition(const BlockProblem& p, const Iterate& it, const Eigen::MatrixXd& V) {
    // Column-major right-hand side: Eigen's sparse triangular solves are slow on row-major ones.
    const Eigen::MatrixXd Vt = V.transpose();
    Eigen::MatrixXd Zt;
    if (p.schwarz != nullptr) {
        Zt = p.schwarz->Solve(Vt);
    } else if (p.hessian != nullptr && p.hessian->valid()) {
        Zt = p.hessian->Solve(Vt);
    } else {
        Zt = p.precon->solve(Vt);
    }
    // With translations eliminated, the rotation rows of Q^{-1} [0; V_R] are exactly
    // (Q_RR - Q_RT Q_TT^{-1} Q_TR)^{-1} V_R: the reduced problem's Euclidean Hessian inverse.
    Eigen::MatrixXd Z = Zt.transpose();
    if (p.elim != nullptr) p.elim->ZeroTranslations(&Z);
    return ProjectToTangent(it.X, Z, p.d);
}

struct TcgResult {
    Eigen::MatrixXd eta;
    Eigen::MatrixXd Heta;
    bool hit_boundary = false;
    int iterations = 0;
};

// Steihaug-Toint truncated CG in the preconditioner's norm (Manopt tCG, theta = 1, kappa = 0.1).
// Manopt's residual target r0 min(r0, kappa) uses the gradient's absolute size: on a problem
// whose gradient is already small it asks for far more accuracy than the stopping test needs
// (parking-garage). The target is therefore never below `floor`
// (BlockRtrOptions::tcg_residual_floor * the gradient tolerance).
TcgResult TruncatedCg(const BlockProblem& p, const Iterate& it, double radius, int max_iter,
                      double floor) {
    TcgResult out;
    out.eta = Eigen::MatrixXd::Zero(it.X.rows(), it.X.cols());
    out.Heta = out.eta;
    Eigen::MatrixXd r = it.rgrad;
    Eigen::MatrixXd z = Precondition(p, it, r);
    double rz = Inner(r, z);
    Eigen::MatrixXd delta = -z;
    double e_Pe = 0.0, e_Pd = 0.0, d_Pd = rz;
    const double r0 = r.norm();
    const double stop = std::max(r0 * std::min(r0, 0.1), floor);
    for (int j = 0; j < max_iter; ++j) {
        out.iterations = j + 1;
        const Eigen::MatrixXd Hd = Hessian(p, it, delta);
        const double dHd = Inner(delta, Hd);
        const double alpha = rz / dHd;
        const double e_Pe_new = e_Pe + 2.0 * alpha * e_Pd + alpha * alpha * d_Pd;
        if (dHd <= 0.0 || e_Pe_new >= radius * radius) {
            const double tau =
                (-e_Pd + std::sqrt(e_Pd * e_Pd + d_Pd * (radius * radius - e_Pe))) / d_Pd;
            out.eta += tau * delta;
            out.Heta += tau * Hd;
            out.hit_boundary = true;
            return out;
        }
        e_Pe = e_Pe_new;
        out.eta += alpha * delta;
        out.Heta += alpha * Hd;
        r += alpha * Hd;
        r = ProjectToTangent(it.X, r, p.d);
        if (r.norm() <= stop) return out;
        z = Precondition(p, it, r);
        const double rz_old = rz;
        rz = Inner(r, z);
        const double beta = rz / rz_old;
        delta = -z + beta * delta;
        e_Pd = beta * (e_Pd + alpha * d_Pd);
        d_Pd = rz + beta * beta * d_Pd;
    }
    return out;
}

}  // namespace

HessianPreconditioner::HessianPreconditioner(const Eigen::SparseMatrix<double>& Q, int d)
    : Q_(&Q), d_(d) {
    const int b = d + 1;
    const int k = static_cast<int>(Q.cols()) / b;
    std::vector<Eigen::Triplet<double>> triplets;
    triplets.reserve(Q.nonZeros() + static_cast<size_t>(k) * d * d + 1);
    for (int c = 0; c < Q.outerSize(); ++c) {
        for (Eigen::SparseMatrix<double>::InnerIterator it(Q, c); it; ++it) {
            triplets.emplace_back(static_cast<int>(it.row()), c, it.value());
            if (it.row() == c) scale_ = std::max(scale_, it.value());
        }
    }
    if (scale_ <= 1.0) scale_ = std::max(scale_, 1.0);
    for (int i = 0; i < k; ++i) {
        for (int a = 0; a < d; ++a) {
            for (int c = 0; c < d; ++c) triplets.emplace_back(b * i + a, b * i + c, 0.0);
        }
    }
    // The translation gauge (all translations moved together) is a null direction of Q_aa
    // and S_aa when the block has no neighbour: anchor the first translation.
    if (k > 0) triplets.emplace_back(d, d, scale_);
    base_.resize(Q.rows(), Q.cols());
    base_.setFromTriplets(triplets.begin(), triplets.end());
    base_.makeCompressed();
    for (int i = 0; i < k; ++i) {
        for (int a = 0; a < d; ++a) {
            for (int c = 0; c < d; ++c)
                block_index_.push_back(ValueIndex(base_, b * i + a, b * i + c));
            diag_index_.push_back(ValueIndex(base_, b * i + a, b * i + a));
        }
    }
    factor_.cholmod().print = 0;  // an indefinite S_aa is an expected outcome
    factor_.setMode(Eigen::CholmodSupernodalLLt);
    factor_.analyzePattern(base_);
}

bool HessianPreconditioner::Refactor(const Eigen::MatrixXd& X, const Eigen::MatrixXd& egrad) {
    const int b = d_ + 1;
    const int k = static_cast<int>(X.cols()) / b;
    CERTISLAM_CHECK(X.cols() == Q_->cols() && egrad.cols() == X.cols());
    Eigen::SparseMatrix<double> S = base_;
    double* values = S.valuePtr();
    size_t index = 0;
    for (int i = 0; i < k; ++i) {  // Lambda_i = sym(Y_i^T (X Q + G)_i) = sym(Y_i^T egrad_i) / 2
        const Eigen::MatrixXd P = X.middleCols(b * i, d_).transpose() * egrad.middleCols(b * i, d_);
        for (int a = 0; a < d_; ++a) {
            for (int c = 0; c < d_; ++c)
                values[block_index_[index++]] -= 0.25 * (P(a, c) + P(c, a));
        }
    }
    const double floor = min_shift * scale_;
    double mu = last_shift_ > 0.0 ? std::max(floor, 0.01 * last_shift_) : floor;
    valid_ = false;
    for (int attempt = 0; attempt < max_attempts; ++attempt, mu *= 100.0) {
        Eigen::SparseMatrix<double> M = S;
        for (int idx : diag_index_) M.valuePtr()[idx] += mu;
        factor_.factorize(M);
        ++factorizations_;
        if (factor_.info() == Eigen::Success) {
            valid_ = true;
            last_shift_ = mu;
            return true;
        }
    }
    last_shift_ = 0.0;
    return false;
}

Eigen::MatrixXd HessianPreconditioner::Solve(const Eigen::MatrixXd& B) const {
    return factor_.solve(B);
}

double BlockCost(const BlockProblem& problem, const Eigen::MatrixXd& X) {
    return CostOnly(problem, X);
}

double BlockGradNorm(const BlockProblem& problem, const Eigen::MatrixXd& X) {
    BlockProblem explicit_problem = problem;  // the gradient at X as it is, translations too
    explicit_problem.elim = nullptr;
    return Evaluate(explicit_problem, X).grad_norm;
}

BlockRtrOutcome SolveBlockRtr(const BlockProblem& p, const BlockRtrOptions& options,
                              Eigen::MatrixXd* X) {
    CERTISLAM_CHECK(p.Q && (p.precon || p.schwarz) && X);
    CERTISLAM_CHECK(p.schwarz == nullptr || p.hessian == nullptr);  // one preconditioner
    Iterate it = Evaluate(p, *X);
    if (p.hessian != nullptr) p.hessian->Refactor(it.X, it.egrad);
    BlockRtrOutcome out;
    out.cost_before = it.cost;
    out.grad_norm_before = it.grad_norm;
    const double tol = std::max(options.grad_tol, options.grad_reduction * it.grad_norm);
    // Initial radius: the preconditioned gradient's size, about the Newton step's (M-norm).
    double radius = std::sqrt(std::max(Inner(it.rgrad, Precondition(p, it, it.rgrad)), 0.0));
    const double max_radius = 1e3 * std::max(radius, 1e-12);
    int last_tcg_iterations = 0;
    while (out.iterations < options.max_iterations && it.grad_norm > tol && radius > 1e-14) {
        ++out.iterations;
        // Told only when another CG run follows: an escalation right before the end is wasted.
        if (p.schwarz != nullptr) p.schwarz->ReportCgIterations(last_tcg_iterations);
        const int cg_cap = p.schwarz != nullptr
                               ? p.schwarz->IterationCap(options.max_tcg_iterations)
                               : options.max_tcg_iterations;
        const TcgResult step = TruncatedCg(p, it, radius, cg_cap, options.tcg_residual_floor * tol);
        last_tcg_iterations = step.iterations;
        Eigen::MatrixXd X_new = Retract(it.X, step.eta, p.d);
        if (p.elim != nullptr) p.elim->OptimizeTranslations(&X_new, p.G);
        const CostChange change = CostDifference(p, it.X, X_new);
        const double model = -Inner(it.rgrad, step.eta) - 0.5 * Inner(step.eta, step.Heta);
        // Manopt's rho regularisation keeps rho meaningful when both decreases are tiny; the
        // cost change is computed directly (CostDifference), its own noise is far smaller.
        const double reg = std::max(
            1e3 * std::numeric_limits<double>::epsilon() * std::max(1.0, std::abs(it.cost)),
            kNoiseMultiple * change.noise);
        const double rho = (-change.value + reg) / (model + reg);
        if (rho < 0.25) {
            radius *= 0.25;
        } else if (rho > 0.75 && step.hit_boundary) {
            radius = std::min(2.0 * radius, max_radius);
        }
        if (rho > 0.1 && change.value <= reg) {
            it = Evaluate(p, std::move(X_new), /*translations_optimal=*/true);
            if (p.hessian != nullptr) p.hessian->Refactor(it.X, it.egrad);
            ++out.accepted;
        }
    }
    out.cost_after = it.cost;
    out.grad_norm_after = it.grad_norm;
    *X = std::move(it.X);
    return out;
}

}  // namespace certislam::slam
