// Riemannian trust region with truncated (Steihaug-Toint) preconditioned CG, as in Absil et al.
// "Trust-region methods on Riemannian manifolds" (2007) and Manopt's trustregions/tCG; the
// Hessian is exact: Proj(2 V Q - V sym(Y^T egrad)) on rotation blocks (Weingarten term).
#include "slam/rbcd_block.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "slam/check.h"
#include "slam/stiefel.h"

namespace certislam::slam {
namespace {

constexpr double kNoiseMultiple = 10.0;  ///< rho regularisation in units of the cost noise

double Inner(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B) { return A.cwiseProduct(B).sum(); }

// The state at one iterate: cost, Euclidean and Riemannian gradients.
struct Iterate {
    Eigen::MatrixXd X;
    Eigen::MatrixXd egrad;
    Eigen::MatrixXd rgrad;
    double cost = 0.0;
    double grad_norm = 0.0;
    double noise = 0.0;  // rounding error of `cost`: eps ||X|| ||egrad|| (a sum of large terms)
};

Iterate Evaluate(const BlockProblem& p, Eigen::MatrixXd X) {
    Iterate it;
    it.egrad = X * (*p.Q);
    it.cost = Inner(it.egrad, X);
    if (p.G && p.G->size() > 0) {
        it.cost += 2.0 * Inner(X, *p.G);
        it.egrad += *p.G;
    }
    it.egrad *= 2.0;
    it.rgrad = ProjectToTangent(X, it.egrad, p.d);
    it.grad_norm = it.rgrad.norm();
    it.noise = std::numeric_limits<double>::epsilon() * X.norm() * it.egrad.norm();
    it.X = std::move(X);
    return it;
}

double CostOnly(const BlockProblem& p, const Eigen::MatrixXd& X) {
    double f = Inner(X * (*p.Q), X);
    if (p.G && p.G->size() > 0) f += 2.0 * Inner(X, *p.G);
    return f;
}

Eigen::MatrixXd Hessian(const BlockProblem& p, const Iterate& it, const Eigen::MatrixXd& V) {
    Eigen::MatrixXd H = 2.0 * (V * (*p.Q));
    H -= WeingartenTerm(it.X, it.egrad, V, p.d);
    return ProjectToTangent(it.X, H, p.d);
}

Eigen::MatrixXd Precondition(const BlockProblem& p, const Iterate& it, const Eigen::MatrixXd& V) {
    // Column-major right-hand side: Eigen's sparse triangular solves are slow on row-major ones.
    const Eigen::MatrixXd Vt = V.transpose();
    const Eigen::MatrixXd Z = p.precon->solve(Vt).transpose();
    return ProjectToTangent(it.X, Z, p.d);
}

struct TcgResult {
    Eigen::MatrixXd eta;
    Eigen::MatrixXd Heta;
    bool hit_boundary = false;
};

// Steihaug-Toint truncated CG in the preconditioner's norm (Manopt tCG, theta = 1, kappa = 0.1).
TcgResult TruncatedCg(const BlockProblem& p, const Iterate& it, double radius, int max_iter) {
    TcgResult out;
    out.eta = Eigen::MatrixXd::Zero(it.X.rows(), it.X.cols());
    out.Heta = out.eta;
    Eigen::MatrixXd r = it.rgrad;
    Eigen::MatrixXd z = Precondition(p, it, r);
    double rz = Inner(r, z);
    Eigen::MatrixXd delta = -z;
    double e_Pe = 0.0, e_Pd = 0.0, d_Pd = rz;
    const double r0 = r.norm();
    const double stop = r0 * std::min(r0, 0.1);
    for (int j = 0; j < max_iter; ++j) {
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

double BlockCost(const BlockProblem& problem, const Eigen::MatrixXd& X) {
    return CostOnly(problem, X);
}

double BlockGradNorm(const BlockProblem& problem, const Eigen::MatrixXd& X) {
    return Evaluate(problem, X).grad_norm;
}

BlockRtrOutcome SolveBlockRtr(const BlockProblem& p, const BlockRtrOptions& options,
                              Eigen::MatrixXd* X) {
    CERTISLAM_CHECK(p.Q && p.precon && X);
    Iterate it = Evaluate(p, *X);
    BlockRtrOutcome out;
    out.cost_before = it.cost;
    out.grad_norm_before = it.grad_norm;
    const double tol = std::max(options.grad_tol, options.grad_reduction * it.grad_norm);
    // Initial radius: the preconditioned gradient's size, about the Newton step's (M-norm).
    double radius = std::sqrt(std::max(Inner(it.rgrad, Precondition(p, it, it.rgrad)), 0.0));
    const double max_radius = 1e3 * std::max(radius, 1e-12);
    while (out.iterations < options.max_iterations && it.grad_norm > tol && radius > 1e-14) {
        ++out.iterations;
        const TcgResult step = TruncatedCg(p, it, radius, options.max_tcg_iterations);
        Eigen::MatrixXd X_new = Retract(it.X, step.eta, p.d);
        const double f_new = CostOnly(p, X_new);
        const double model = -Inner(it.rgrad, step.eta) - 0.5 * Inner(step.eta, step.Heta);
        // Manopt's rho regularisation keeps rho meaningful when both decreases are tiny.
        // Also above the cost's own rounding noise: on metric-scale maps with a small f
        // (parking-garage) tr(X Q X^T) is a sum of terms 1e6 times larger than f, and rho made of
        // noise rejects every step near the optimum although the gradient is still exact.
        const double reg = std::max(
            1e3 * std::numeric_limits<double>::epsilon() * std::max(1.0, std::abs(it.cost)),
            kNoiseMultiple * it.noise);
        const double rho = (it.cost - f_new + reg) / (model + reg);
        if (rho < 0.25) {
            radius *= 0.25;
        } else if (rho > 0.75 && step.hit_boundary) {
            radius = std::min(2.0 * radius, max_radius);
        }
        if (rho > 0.1 && f_new <= it.cost + reg) {
            it = Evaluate(p, std::move(X_new));
            ++out.accepted;
        }
    }
    out.cost_after = it.cost;
    out.grad_norm_after = it.grad_norm;
    *X = std::move(it.X);
    return out;
}

}  // namespace certislam::slam
