// The dual certificate of the rank-r relaxation: S = Q - blockdiag(Lambda(X)), its verdict and
// smallest eigenpair (MATH.md, "The certificate"; SE-Sync, Rosen et al. IJRR 2019, Sec. 4.2-4.3).
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace certislam::certify {

/// Settings of the certifier; every tolerance is relative to the problem's own scale.
struct CertificateConfig {
    /// eta = eta_relative * ||Q||, ||Q|| bounded above by its largest absolute row sum.
    /// S + eta D PSD (D = identity on rotation entries, zero on translations) proves
    /// f* >= tr(Lambda) - eta * d * n exactly (the rotation diagonal blocks of any feasible Z
    /// are I_d); "certified" also needs that bound tight (max_relative_bound). 1e-7 sits well above
    /// the rounding noise of S (about 1e-15 ||Q||) and of a point stopped at
    /// gradient_tolerance_relative, and well below the negative curvature of real saddles (MATH.md;
    /// Shonan's false certificates came from a loose tolerance, not from eta).
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
    /// "certified" requires a proven relative suboptimality bound (f(X) - lower_bound) / f(X)
    /// at most this, in (0, 1): S + eta D PSD alone only says X is within eta d n of f*.
    double max_relative_bound = 1e-6;

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// Everything the certificate says about X; every quantity SE-Sync names is here. The bound
/// fields are zero unless has_bound: a lower bound exists only once S + eta D was shown PSD.
struct CertificateResult {
    /// The verdict; VerdictName gives its one spelling in every report.
    enum class Status {
        kCertified,  ///< critical, S + eta D PSD, relative bound <= max_relative_bound
        /// critical, S + eta D not PSD (x^T S x < -eta x^T D x for some x; lambda_min < -eta
        /// unless its eigenvector has translation entries), lambda_min < 0: a saddle; its
        /// eigenvector escapes (escape_descent)
        kNotOptimal,
        kNotCritical,   ///< gradient above its tolerance: no bound, no eigenvalue (meaningless)
        kInconclusive,  ///< critical but neither proven optimal nor refuted: `reason` says why
    };
    Status status = Status::kInconclusive;
    std::string reason;      ///< kInconclusive: why (empty otherwise)
    bool has_bound = false;  ///< lower_bound and the suboptimality bounds below are proven
    /// S + eta D is PSD: a sparse Cholesky of S + e D succeeded for some e <= eta
    bool psd_at_eta = false;
    double objective = 0.0;            ///< f(X) = tr(X Q X^T), SE-Sync objective (no 1/2)
    double dual_value = 0.0;           ///< tr(Lambda)
    double duality_gap = 0.0;          ///< f(X) - tr(Lambda) (= tr(X S X^T))
    double eta = 0.0;                  ///< absolute eta used
    double q_norm = 0.0;               ///< the upper bound of ||Q||_2 eta is relative to
    double bound_eta = 0.0;            ///< smallest eta found with S + eta D PSD (<= eta)
    double lower_bound = 0.0;          ///< max(tr(Lambda) - bound_eta d n, 0) <= f*
    double suboptimality_bound = 0.0;  ///< f(X) - lower_bound >= f(X) - f*
    /// suboptimality_bound / f(X) (f(X) floored at its rounding floor, so f* = 0 gives 0)
    double objective_noise = 0.0;  ///< rounding floor of f(X) (ObjectiveOfColumns)
    double relative_suboptimality_bound = 0.0;
    double lambda_min = 0.0;           ///< Rayleigh quotient v^T S v of the computed eigenvector
    double lambda_min_relative = 0.0;  ///< lambda_min / ||Q||
    double eigen_residual = 0.0;       ///< ||S v - lambda_min v||
    Eigen::VectorXd eigenvector;       ///< unit v, length (d+1)n, layout of X's columns
    /// kNotOptimal: f(X) - f(X_+) > 0 at the escape point X_+ of rank r + 1 along v
    /// (EscapeSaddle), and its step; 0 if no step of the line search decreased f.
    double escape_descent = 0.0;
    double escape_step = 0.0;
    double gradient_norm = 0.0;       ///< ||X S||_F * 2 (the Riemannian gradient if Lambda(X))
    double gradient_tolerance = 0.0;  ///< the absolute first-order tolerance applied
    int eigen_iterations = 0;         ///< Lanczos restarts used
    int shift_attempts = 0;           ///< Cholesky factorizations spent finding the shift
    double seconds = 0.0;             ///< wall time of Certify
};

/// "certified", "not optimal", "not critical" or "inconclusive".
const char* VerdictName(CertificateResult::Status status);

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

/// The first-order quantities of a certificate, however they were computed (one process, or
/// sums over robots): every one from the same X on the same graph.
struct CertificateQuantities {
    int d = 3;                     ///< dimension
    int n = 0;                     ///< poses
    double objective = 0.0;        ///< f(X) = tr(X Q X^T)
    double dual_value = 0.0;       ///< tr(Lambda)
    double q_norm = 0.0;           ///< upper bound of ||Q||_2 (NormUpperBound)
    double gradient_norm = 0.0;    ///< ||2 X S||_F
    double x_norm = 0.0;           ///< ||X||_F (scale of the rounding noise of X Q)
    double objective_noise = 0.0;  ///< rounding floor of f(X) (ObjectiveOfColumns)
};

/// f(X) summed over some of Q's columns, and its rounding floor.
struct ObjectiveShare {
    double value = 0.0;  ///< sum over the columns c of X_c^T (X Q)_c, for Q's doubles exactly
    /// How far `value` may lie from f(X) for the exact Laplacian of the measurements as read
    /// (Q's rounding, weighed by |X|^T |Q| |X|): where f(X) is below it, X is as good as an exact
    /// optimum of f* = 0 to the precision of the problem's doubles.
    double noise = 0.0;
};

/// f(X) = tr(X Q X^T) over columns [begin, end) of Q (Q symmetric; X r x Q.rows()), summed in
/// quadruple precision: the Laplacian form cancels terms of size |X|^T |Q| |X|, so summed in
/// doubles its own error would exceed the floor below.
ObjectiveShare ObjectiveOfColumns(const Eigen::SparseMatrix<double>& Q, const Eigen::MatrixXd& X,
                                  Eigen::Index begin, Eigen::Index end);

/// A PSD test of S + e D for the S of one X and one graph (monotone in e).
using PsdTestFunction = std::function<bool(double e)>;

/// The Cholesky test of S + e D (gauge-fixed, CHOLMOD; the symbolic analysis is done once).
PsdTestFunction MakePsdTest(const Eigen::SparseMatrix<double>& S, int d);

/// First-order part of the one verdict: fills objective, dual value, duality gap, q_norm, eta,
/// gradient norm and its tolerance; true when X is critical (gradient within tolerance). Not
/// critical: status kNotCritical, no bound.
bool FirstOrderVerdict(const CertificateQuantities& q, const CertificateConfig& config,
                       CertificateResult* result);

/// Second-order part of the one verdict at a critical X: from lambda_min (nullopt: the
/// eigensolver failed) and psd_at on the same S, sets status, reason, psd_at_eta and, when S +
/// eta D was shown PSD, the bound (VerdictAndBound); certified needs the relative bound within
/// config.max_relative_bound. Computes no escape (the caller holds Q and X).
void SecondOrderVerdict(const CertificateQuantities& q, std::optional<double> lambda_min,
                        const CertificateConfig& config, const PsdTestFunction& psd_at,
                        CertificateResult* result);

/// Certifies X (r x (d+1)n, blocks [Y_i p_i], Y_i on the Stiefel manifold) for f = tr(X Q X^T),
/// with Lambda recomputed from X (LambdaBlocks): never a solver's multipliers (MATH.md).
CertificateResult Certify(const Eigen::SparseMatrix<double>& Q, const Eigen::MatrixXd& X, int d,
                          const CertificateConfig& config = {});

/// The same verdict for given multipliers (one symmetric d x d block per pose), e.g. blocks
/// assembled from robots' messages: the first-order test is on the Lagrangian gradient 2 X S,
/// so zero or stale multipliers come out "not critical", and a bound needs S + eta D PSD.
CertificateResult CertifyWithMultipliers(const Eigen::SparseMatrix<double>& Q,
                                         const Eigen::MatrixXd& X, int d,
                                         const std::vector<Eigen::MatrixXd>& lambda,
                                         const CertificateConfig& config = {});

}  // namespace certislam::certify
