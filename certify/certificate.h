// The dual certificate of the rank-r relaxation: S = Q - blockdiag(Lambda(X)), its verdict and
// smallest eigenpair (MATH.md, "The certificate"; SE-Sync, Rosen et al. IJRR 2019, Sec. 4.2-4.3).
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <cstdint>
#include <functional>
#include <vector>

namespace certislam::certify {

/// Settings of the certifier; every tolerance is relative to the problem's own scale.
struct CertificateConfig {
    /// eta = eta_relative * ||Q||, ||Q|| bounded above by its largest absolute row sum.
    /// Certified means S + eta D is PSD (D = identity on rotation entries, zero on
    /// translations), hence f* >= tr(Lambda) - eta * d * n exactly (the rotation diagonal
    /// blocks of any feasible Z are I_d). 1e-7 sits well above the rounding noise of S
    /// (about 1e-15 ||Q||) and of a point stopped at gradient_tolerance_relative, and well
    /// below the negative curvature of real saddles (MATH.md; Shonan's false certificates came
    /// from a loose tolerance, not from eta).
    double eta_relative = 1e-7;
    /// First-order tolerance: certify only if ||grad f||_F <= this * 2 sqrt(||Q|| f(X)). The
    /// scale is an upper bound of ||grad f|| itself (||XQ||_F^2 <= ||Q|| f), so the test is
    /// invariant to the units of the weights and of the map.
    double gradient_tolerance_relative = 1e-4;
    /// Convergence tolerance of the Lanczos iteration on (S - sigma I)^{-1} (Spectra's rule:
    /// residual <= tol * |Ritz value|).
    double eigen_tolerance = 1e-12;
    int eigen_max_iterations = 1000;  ///< Lanczos restarts, > 0
    int eigen_subspace = 24;          ///< Lanczos basis size (ncv), >= 3
    std::uint64_t seed = 20261121;    ///< seed of the Lanczos start vector (fixed: reproducible)
    /// After a certified verdict the lower bound f* >= tr(Lambda) - eta d n is tightened down
    /// to eta * 10^-bound_refinements (the verdict's eta is meant to be safe, not tight; at a
    /// well-converged optimum S is PSD to rounding noise): first one factorization at
    /// max(4 |lambda_min|, that floor), then, if it fails, the smallest eta 10^-k above it at
    /// which S + eta D still factorizes (VerdictAndBound below: the nearest rung first, then
    /// bisection on k). >= 0; 0: the bound stays at the verdict's eta.
    int bound_refinements = 6;

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// Everything the certificate says about X; every quantity SE-Sync names is here.
struct CertificateResult {
    enum class Status {
        kCertified,          ///< critical and S + eta D PSD: X is (numerically) globally optimal
        kNotCertified,       ///< critical, but S has a negative eigenvalue below -eta
        kNotCritical,        ///< gradient above tolerance: no verdict (it would mean nothing)
        kEigensolverFailed,  ///< critical, verdict made, but the eigenpair did not converge
    };
    Status status = Status::kEigensolverFailed;
    /// S + eta D is PSD: a sparse Cholesky of S + e D succeeded for some e <= eta
    bool psd_at_eta = false;
    double cost = 0.0;                 ///< f(X) = tr(X Q X^T), SE-Sync objective (no 1/2)
    double dual_value = 0.0;           ///< tr(Lambda)
    double duality_gap = 0.0;          ///< f(X) - tr(Lambda) (= <grad, X>/2)
    double eta = 0.0;                  ///< absolute eta used
    double q_norm = 0.0;               ///< the upper bound of ||Q||_2 eta is relative to
    double bound_eta = 0.0;            ///< smallest eta found with S + eta D PSD (<= eta)
    double lower_bound = 0.0;          ///< tr(Lambda) - bound_eta d n <= f*; valid if psd_at_eta
    double suboptimality_bound = 0.0;  ///< f(X) - lower_bound; valid if psd_at_eta
    double relative_suboptimality_bound = 0.0;  ///< suboptimality_bound / f(X)
    double lambda_min = 0.0;           ///< Rayleigh quotient v^T S v of the computed eigenvector
    double lambda_min_relative = 0.0;  ///< lambda_min / ||Q||
    double eigen_residual = 0.0;       ///< ||S v - lambda_min v||
    Eigen::VectorXd eigenvector;       ///< unit v, length (d+1)n, layout of X's columns
    double gradient_norm = 0.0;        ///< ||grad f(X)||_F (Riemannian, = 2 ||X S||_F)
    double gradient_tolerance = 0.0;   ///< the absolute first-order tolerance applied
    int eigen_iterations = 0;          ///< Lanczos restarts used
    int shift_attempts = 0;            ///< Cholesky factorizations spent finding the shift
    double seconds = 0.0;              ///< wall time of Certify
};

/// Lambda_i = sym((X Q)[:, rotation columns of i]^T Y_i), one d x d block per pose.
std::vector<Eigen::MatrixXd> LambdaBlocks(const Eigen::SparseMatrix<double>& Q,
                                          const Eigen::MatrixXd& X, int d);

/// S = Q - blockdiag(Lambda) with zeros on translation entries; same pattern as Q.
Eigen::SparseMatrix<double> CertificateMatrix(const Eigen::SparseMatrix<double>& Q,
                                              const std::vector<Eigen::MatrixXd>& lambda, int d);

/// Upper bound of ||Q||_2: the largest absolute row sum (Gershgorin).
double NormUpperBound(const Eigen::SparseMatrix<double>& Q);

/// The largest k in [pass, fail) with ok(k), given ok(pass) and ok monotone (true up to some k,
/// false after it), by bisection: ceil(log2(fail - pass)) calls of ok.
int LastPassing(int pass, int fail, const std::function<bool(int)>& ok);

/// What VerdictAndBound found.
struct BoundSearch {
    bool psd_at_eta = false;  ///< the verdict: S + eta D is PSD (shown at eta or below it)
    double bound_eta = 0.0;   ///< smallest eta shown PSD (eta itself if none smaller); if verdict
    int factorizations = 0;   ///< calls of psd_at
};

/// The verdict (SE-Sync's fast verification: S + eta D PSD) and the eta of the tightened lower
/// bound f* >= tr(Lambda) - eta d n, from psd_at(e) (a Cholesky test of S + e D, monotone in e:
/// D >= 0, so PSD at e means PSD above it; a PSD test below eta is the verdict too). First e =
/// max(4 |lambda_min|, eta 10^-bound_refinements) (S + e D is not PSD below -lambda_min, and at
/// a well-converged optimum one test there settles both); if it fails, the rung eta 10^-k just
/// above it (the eta needed is usually there: torus3D --robots 1), then the verdict at eta,
/// then bisection on k for the smallest PSD rung. Certified: 1-2 tests usually, at most
/// 3 + ceil(log2(bound_refinements)); not certified: 1 test when 4 |lambda_min| >= eta, else 3.
/// Same verdict and bound as stepping down the ladder from eta while it stays PSD (up to
/// 1 + bound_refinements tests). bound_refinements 0: one test at eta.
BoundSearch VerdictAndBound(double eta, double lambda_min, int bound_refinements,
                            const std::function<bool(double)>& psd_at);

/// Certifies X (r x (d+1)n, blocks [Y_i p_i], Y_i on the Stiefel manifold) for f = tr(X Q X^T).
CertificateResult Certify(const Eigen::SparseMatrix<double>& Q, const Eigen::MatrixXd& X, int d,
                          const CertificateConfig& config = {});

}  // namespace certislam::certify
