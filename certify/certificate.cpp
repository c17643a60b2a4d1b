// Lambda(X), S = Q - blockdiag(Lambda), the Cholesky verdict and the smallest eigenpair.
#include "certify/certificate.h"

#include <Eigen/CholmodSupport>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "certify/min_eigenpair.h"
#include "certify/saddle_escape.h"
#include "slam/core/check.h"
#include "slam/core/pose_graph.h"

namespace certislam::certify {
namespace {

using SparseMatrix = Eigen::SparseMatrix<double>;
using slam::BlockColumn;

constexpr double kRoundingNoise = 1e-12;        ///< relative noise of a product X Q in doubles
constexpr double kBoundRefinementFactor = 0.1;  ///< eta step of the lower-bound refinement
constexpr double kLambdaMargin = 4.0;           ///< first refined eta in units of -lambda_min
constexpr int kMaxRefinements = 12;             ///< eta 10^-12: S's rounding noise is near
constexpr double kManifoldTolerance = 1e-8;     ///< ||Y_i^T Y_i - I||_F of a point on St(d, r)
/// Ulps within which each entry of Q lies of the exact Laplacian of the measurements as read
/// (ConnectionLaplacian: a few roundings per edge, then a sum over a pose's edges)
constexpr double kLaplacianUlps = 32.0;

// Quadruple precision for the objective's sums: 113 significant bits, so a product of two
// doubles is exact. __float128 on x86-64; where it is missing (aarch64) long double is quad.
#if defined(__SIZEOF_FLOAT128__)
__extension__ typedef __float128 Quad;
constexpr double kQuadEpsilon = 1.0 / 5192296858534827628530496329220096.0;  // 2^-112
#else
typedef long double Quad;
constexpr double kQuadEpsilon = std::numeric_limits<long double>::epsilon();
#endif

void Require(bool ok, const std::string& field, double value, const std::string& rule) {
    if (!ok) {
        throw std::invalid_argument("CertificateConfig." + field + " = " + std::to_string(value) +
                                    ": must be " + rule);
    }
}

/// (S + eta D) with the translation row and column of pose 0 deleted. S 1_t = 0 and D 1_t = 0
/// for the translation gauge vector 1_t (ones on translation entries), so for any x,
/// x^T (S + eta D) x = y^T (S + eta D) y with y = x - (x_t0) 1_t, which has y_t0 = 0: the full
/// matrix is PSD exactly when this principal submatrix is, and the submatrix is definite at an
/// optimum (its remaining null directions, the rows of X, all have rotation entries).
SparseMatrix GaugeFixedShifted(const SparseMatrix& S, int d, double eta) {
    const int removed = d;  // translation entry of pose 0
    std::vector<Eigen::Triplet<double>> triplets;
    triplets.reserve(S.nonZeros() + S.rows());
    for (int k = 0; k < S.outerSize(); ++k) {
        for (SparseMatrix::InnerIterator it(S, k); it; ++it) {
            if (it.row() == removed || it.col() == removed) continue;
            const int r = it.row() > removed ? it.row() - 1 : it.row();
            const int c = it.col() > removed ? it.col() - 1 : it.col();
            triplets.emplace_back(r, c, it.value());
        }
    }
    for (int i = 0; i < S.rows(); ++i) {
        if (i % (d + 1) == d) continue;  // translation entry: no shift
        const int r = i > removed ? i - 1 : i;
        triplets.emplace_back(r, r, eta);
    }
    SparseMatrix M(S.rows() - 1, S.cols() - 1);
    M.setFromTriplets(triplets.begin(), triplets.end());
    return M;
}

/// Cholesky tests of S + eta D for several eta: the gauge-fixed matrix and CHOLMOD's symbolic
/// analysis are built once, each eta costs one numeric factorization of that matrix with its
/// shifted diagonal set in place (no copy of it of our own beside CHOLMOD's: the anchor's peak
/// memory is that factorization).
class PsdTest {
  public:
    // The lower triangle alone: the factorisation reads no more (half the copies per test).
    PsdTest(const SparseMatrix& S, int d)
        : base_(GaugeFixedShifted(S, d, 0.0).triangularView<Eigen::Lower>()) {
        base_.makeCompressed();
        for (int i = 0; i < S.rows(); ++i) {
            if (i % (d + 1) == d) continue;  // translation entry: no shift
            const int r = i > d ? i - 1 : i;
            // GaugeFixedShifted stored every shifted diagonal entry (an explicit 0 + eta).
            const auto* first = base_.innerIndexPtr() + base_.outerIndexPtr()[r];
            const auto* last = base_.innerIndexPtr() + base_.outerIndexPtr()[r + 1];
            const auto* at = std::find(first, last, r);
            CERTISLAM_CHECK(at != last && *at == r);
            const auto k = static_cast<std::size_t>(at - base_.innerIndexPtr());
            shifted_.emplace_back(k, base_.valuePtr()[k]);
        }
        factor_.cholmod().print = 0;  // a failure is an expected outcome (not certified)
        factor_.setMode(Eigen::CholmodSupernodalLLt);  // LDL^T would accept indefinite matrices
        factor_.analyzePattern(base_);
    }

    bool PsdAt(double eta) {
        double* values = base_.valuePtr();
        for (const auto& [k, value] : shifted_) values[k] = value + eta;
        factor_.factorize(base_);
        for (const auto& [k, value] : shifted_) values[k] = value;
        return factor_.info() == Eigen::Success;
    }

  private:
    SparseMatrix base_;
    std::vector<std::pair<std::size_t, double>> shifted_;  ///< diagonal entries' value index, value
    Eigen::CholmodDecomposition<SparseMatrix, Eigen::Lower> factor_;
};

/// Why X is not a point of the manifold (Y_i^T Y_i = I_d), or empty: off it, tr(Z D) != d n and
/// neither the bound nor the gap identity holds.
std::string OffManifold(const Eigen::MatrixXd& X, int d) {
    const int n = static_cast<int>(X.cols()) / (d + 1);
    for (int i = 0; i < n; ++i) {
        const Eigen::MatrixXd Y = X.middleCols(slam::BlockColumn(i, d), d);
        const double err = (Y.transpose() * Y - Eigen::MatrixXd::Identity(d, d)).norm();
        if (!(err <= kManifoldTolerance)) {
            return "pose " + std::to_string(i) +
                   " is off the Stiefel manifold (||Y^T Y - I|| = " + std::to_string(err) + ")";
        }
    }
    return {};
}

/// Sets the proven bound of S + bound_eta D PSD (MATH.md: f* >= tr(Lambda) - eta tr(Z D) =
/// tr(Lambda) - eta d n for every feasible Z, and f* >= 0 since f is a sum of squares).
void SetBound(double bound_eta, int d, int n, CertificateResult* result) {
    result->has_bound = true;
    result->bound_eta = bound_eta;
    result->lower_bound = std::max(result->dual_value - bound_eta * d * n, 0.0);
    result->suboptimality_bound = std::max(result->objective - result->lower_bound, 0.0);
}

/// The largest eta whose bound eta d n still certifies: the relative allowance left after the gap
/// f - tr(Lambda), as FinishBound measures it, with a tenth spare; 0 when nothing is left.
double CertifyingEta(const CertificateQuantities& q, const CertificateConfig& config,
                     const CertificateResult& result) {
    const double scale = std::max(result.objective, q.objective_noise);
    const double allowance =
        config.max_relative_bound * scale - (result.objective - result.dual_value);
    return allowance > 0.0 ? 0.9 * allowance / (q.d * q.n) : 0.0;
}

/// Rungs of the bound ladder: config.bound_refinements, or more (up to kMaxRefinements) when
/// eta 10^-k d n must fall below max_relative_bound f(X) for a bound tight enough to certify
/// (graphs whose ||Q|| is large against f, e.g. kitti's odometry weights).
int Refinements(const CertificateConfig& config, int d, int n, const CertificateResult& result) {
    if (config.bound_refinements == 0 || !(result.objective > 0.0)) return config.bound_refinements;
    const double needed_eta = 0.5 * config.max_relative_bound * result.objective / (d * n);
    const int needed = static_cast<int>(std::ceil(std::log10(result.eta / needed_eta)));
    return std::clamp(needed, config.bound_refinements, kMaxRefinements);
}

/// The eigenpair of S at a critical X (nullopt when the eigensolver failed).
std::optional<MinEigenpairResult> Eigenpair(const SparseMatrix& S, double eta,
                                            const CertificateConfig& config,
                                            CertificateResult* result) {
    MinEigenpairConfig eig;
    eig.initial_shift = eta;
    eig.tolerance = config.eigen_tolerance;
    eig.max_iterations = config.eigen_max_iterations;
    eig.subspace = config.eigen_subspace;
    eig.seed = config.seed;
    MinEigenpairResult pair = SmallestEigenpair(S, eig);
    result->eigen_iterations = pair.iterations;
    result->shift_attempts = pair.shift_attempts;
    if (pair.status != MinEigenpairResult::Status::kConverged) return std::nullopt;
    result->eigen_residual = pair.residual;
    result->eigenvector = pair.vector;
    return pair;
}

/// Sets the relative bound and the verdict of a proven bound.
void FinishBound(const CertificateQuantities& q, const CertificateConfig& config,
                 CertificateResult* result) {
    // Relative to f(X) floored at its rounding floor (f* = 0 graphs).
    result->objective_noise = q.objective_noise;
    const double scale = std::max(result->objective, result->objective_noise);
    result->relative_suboptimality_bound = scale > 0.0 ? result->suboptimality_bound / scale : 0.0;
    // f* >= 0 (a sum of squares), so f(X) - f* <= f(X): where f(X) is within the rounding floor
    // of Q's doubles (a tree, kitti_08: f* = 0), X is optimal to the precision of the problem's
    // doubles, though no bound relative to f(X) can be proven.
    if (result->objective <= result->objective_noise &&
        result->relative_suboptimality_bound > config.max_relative_bound) {
        result->status = CertificateResult::Status::kCertified;
        char text[128];
        std::snprintf(text, sizeof(text),
                      "f(X) = %.3g is within the rounding floor %.3g of Q's doubles (f* >= 0)",
                      result->objective, result->objective_noise);
        result->reason = text;
        return;
    }
    if (result->relative_suboptimality_bound > config.max_relative_bound) {
        result->status = CertificateResult::Status::kInconclusive;
        char text[128];
        std::snprintf(text, sizeof(text),
                      "S + eta D is PSD but the proven relative suboptimality bound %.3g exceeds "
                      "%.3g",
                      result->relative_suboptimality_bound, config.max_relative_bound);
        result->reason = text;
        return;
    }
    result->status = CertificateResult::Status::kCertified;
}

}  // namespace

void CertificateConfig::Validate() const {
    Require(eta_relative > 0.0 && eta_relative < 1.0, "eta_relative", eta_relative, "in (0, 1)");
    Require(gradient_tolerance_relative > 0.0, "gradient_tolerance_relative",
            gradient_tolerance_relative, "> 0");
    Require(eigen_tolerance > 0.0, "eigen_tolerance", eigen_tolerance, "> 0");
    Require(eigen_max_iterations > 0, "eigen_max_iterations", eigen_max_iterations, "> 0");
    Require(eigen_subspace >= 3, "eigen_subspace", eigen_subspace, ">= 3");
    Require(bound_refinements >= 0, "bound_refinements", bound_refinements, ">= 0");
    Require(max_relative_bound > 0.0 && max_relative_bound < 1.0, "max_relative_bound",
            max_relative_bound, "in (0, 1)");
}

const char* VerdictName(CertificateResult::Status status) {
    switch (status) {
        case CertificateResult::Status::kCertified:
            return "certified";
        case CertificateResult::Status::kNotOptimal:
            return "not optimal";
        case CertificateResult::Status::kNotCritical:
            return "not critical";
        case CertificateResult::Status::kInconclusive:
            break;
    }
    return "inconclusive";
}

std::vector<Eigen::MatrixXd> LambdaBlocks(const SparseMatrix& Q, const Eigen::MatrixXd& X, int d) {
    CERTISLAM_CHECK(X.cols() == Q.rows() && X.cols() % (d + 1) == 0);
    const int n = static_cast<int>(X.cols()) / (d + 1);
    const Eigen::MatrixXd XQ = X * Q;
    std::vector<Eigen::MatrixXd> lambda(n);
    for (int i = 0; i < n; ++i) {
        const int c = BlockColumn(i, d);
        const Eigen::MatrixXd P = XQ.middleCols(c, d).transpose() * X.middleCols(c, d);
        lambda[i] = 0.5 * (P + P.transpose());
    }
    return lambda;
}

SparseMatrix CertificateMatrix(const SparseMatrix& Q, const std::vector<Eigen::MatrixXd>& lambda,
                               int d) {
    std::vector<Eigen::Triplet<double>> triplets;
    triplets.reserve(lambda.size() * d * d);
    for (size_t i = 0; i < lambda.size(); ++i) {
        const int c = BlockColumn(static_cast<int>(i), d);
        for (int a = 0; a < d; ++a) {
            for (int b = 0; b < d; ++b) triplets.emplace_back(c + a, c + b, -lambda[i](a, b));
        }
    }
    SparseMatrix L(Q.rows(), Q.cols());
    L.setFromTriplets(triplets.begin(), triplets.end());
    SparseMatrix S = Q + L;
    S.makeCompressed();
    return S;
}

BoundSearch VerdictAndBound(double eta, double lambda_min, int bound_refinements,
                            const std::function<bool(double)>& psd_at) {
    CERTISLAM_CHECK(eta > 0.0 && bound_refinements >= 0);
    BoundSearch out;
    out.bound_eta = eta;
    auto psd = [&](double e) {
        ++out.factorizations;
        return psd_at(e);
    };
    if (bound_refinements == 0) {
        out.psd_at_eta = psd(eta);
        return out;
    }
    std::vector<double> ladder{eta};  // ladder[k] = eta 10^-k
    for (int k = 0; k < bound_refinements; ++k)
        ladder.push_back(ladder.back() * kBoundRefinementFactor);
    const double target = std::max(kLambdaMargin * std::max(-lambda_min, 0.0), ladder.back());
    if (target < eta && psd(target)) {
        out.psd_at_eta = true;
        out.bound_eta = target;
        return out;
    }
    int fail = static_cast<int>(ladder.size());  // candidates above a failed target only
    while (fail > 1 && ladder[fail - 1] <= target) --fail;
    if (fail > 1 && psd(ladder[fail - 1])) {  // usually just above the target
        out.psd_at_eta = true;
        out.bound_eta = ladder[fail - 1];
        return out;
    }
    out.psd_at_eta = psd(eta);
    if (!out.psd_at_eta) return out;
    if (fail > 1) --fail;  // that rung failed
    out.bound_eta = ladder[LastPassing(0, fail, [&](int k) { return psd(ladder[k]); })];
    return out;
}

int LastPassing(int pass, int fail, const std::function<bool(int)>& ok) {
    CERTISLAM_CHECK(pass < fail);
    while (fail - pass > 1) {
        const int mid = pass + (fail - pass) / 2;
        if (ok(mid)) {
            pass = mid;
        } else {
            fail = mid;
        }
    }
    return pass;
}

double NormUpperBound(const SparseMatrix& Q) {
    Eigen::VectorXd row_sums = Eigen::VectorXd::Zero(Q.rows());
    for (int k = 0; k < Q.outerSize(); ++k) {
        for (SparseMatrix::InnerIterator it(Q, k); it; ++it)
            row_sums[it.row()] += std::abs(it.value());
    }
    return row_sums.size() > 0 ? row_sums.maxCoeff() : 0.0;
}

ObjectiveShare ObjectiveOfColumns(const SparseMatrix& Q, const Eigen::MatrixXd& X,
                                  Eigen::Index begin, Eigen::Index end) {
    CERTISLAM_CHECK(X.cols() == Q.rows() && 0 <= begin && begin <= end && end <= Q.cols());
    Quad sum = 0;
    double magnitude = 0.0;  // |X|^T |Q| |X| over the columns: the size of the cancelled terms
    double terms = 0.0;
    for (Eigen::Index c = begin; c < end; ++c) {
        for (SparseMatrix::InnerIterator it(Q, c); it; ++it) {
            Quad dot = 0;
            double abs_dot = 0.0;
            for (Eigen::Index a = 0; a < X.rows(); ++a) {
                dot += static_cast<Quad>(X(a, it.row())) * static_cast<Quad>(X(a, c));
                abs_dot += std::abs(X(a, it.row()) * X(a, c));
            }
            sum += static_cast<Quad>(it.value()) * dot;
            magnitude += std::abs(it.value()) * abs_dot;
            terms += static_cast<double>(X.rows()) + 1.0;
        }
    }
    constexpr double eps = std::numeric_limits<double>::epsilon();
    ObjectiveShare out;
    out.value = static_cast<double>(sum);
    // Q's doubles differ from the exact Laplacian by up to kLaplacianUlps eps |Q|, which moves
    // f(X) by up to that times |X|^T |Q| |X|: below it f(X) cannot tell X from an exact optimum
    // of f* = 0. The quad sums add at most terms * kQuadEpsilon of it, the final rounding eps.
    out.noise =
        (kLaplacianUlps * eps + terms * kQuadEpsilon) * magnitude + eps * std::abs(out.value);
    return out;
}

CertificateResult Certify(const SparseMatrix& Q, const Eigen::MatrixXd& X, int d,
                          const CertificateConfig& config) {
    return CertifyWithMultipliers(Q, X, d, LambdaBlocks(Q, X, d), config);
}

PsdTestFunction MakePsdTest(const SparseMatrix& S, int d) {
    auto test = std::make_shared<PsdTest>(S, d);
    return [test](double e) { return test->PsdAt(e); };
}

bool FirstOrderVerdict(const CertificateQuantities& q, const CertificateConfig& config,
                       CertificateResult* result) {
    result->objective = q.objective;
    result->dual_value = q.dual_value;
    result->duality_gap = q.objective - q.dual_value;
    result->q_norm = q.q_norm;
    result->eta = config.eta_relative * q.q_norm;
    // Riemannian gradient = 2 X S when Lambda = Lambda(X); else the Lagrangian's gradient.
    result->gradient_norm = q.gradient_norm;
    // The second term is the rounding noise of X Q (it matters only where f(X) = 0).
    const double noise = kRoundingNoise * q.q_norm * q.x_norm;
    result->gradient_tolerance = config.gradient_tolerance_relative * 2.0 *
                                     std::sqrt(q.q_norm * std::max(q.objective, 0.0)) +
                                 noise;
    if (result->gradient_norm > result->gradient_tolerance) {
        result->status = CertificateResult::Status::kNotCritical;
        return false;
    }
    return true;
}

void SecondOrderVerdict(const CertificateQuantities& q, std::optional<double> lambda_min,
                        const CertificateConfig& config, const PsdTestFunction& psd_at,
                        CertificateResult* result) {
    if (!(result->eta > 0.0)) {  // Q = 0 (or sums from a peer that are not numbers)
        result->status = CertificateResult::Status::kInconclusive;
        result->reason = "||Q|| = " + std::to_string(result->q_norm) + ": no scale to test at";
        return;
    }
    if (!lambda_min) {
        // A factorization at eta proves PSD by itself; a failed one, without an eigenvector,
        // neither refutes optimality nor gives a direction.
        result->psd_at_eta = psd_at(result->eta);
        if (!result->psd_at_eta) {
            result->status = CertificateResult::Status::kInconclusive;
            result->reason = "S + eta D did not factorize and the eigensolver failed";
            return;
        }
        SetBound(result->eta, q.d, q.n, result);
        return FinishBound(q, config, result);
    }
    result->lambda_min = *lambda_min;
    result->lambda_min_relative = result->q_norm > 0.0 ? *lambda_min / result->q_norm : 0.0;
    const BoundSearch search =
        VerdictAndBound(result->eta, *lambda_min, Refinements(config, q.d, q.n, *result), psd_at);
    result->psd_at_eta = search.psd_at_eta;
    if (search.psd_at_eta) {
        // The ladder's rungs are a decade apart: when the lowest passing one bounds too loosely
        // to certify, the eta just tight enough may still factorize.
        const double certifying = CertifyingEta(q, config, *result);
        const bool between = certifying > 0.0 && certifying < search.bound_eta;
        SetBound(between && psd_at(certifying) ? certifying : search.bound_eta, q.d, q.n, result);
        return FinishBound(q, config, result);
    }
    // S + eta D not PSD proves x^T S x < -eta x^T D x for some x (D >= 0: S is not PSD either);
    // the eigenvector, v^T S v < 0, is the direction to escape along. lambda_min itself may lie
    // in (-eta, 0) when v has translation entries, which D does not weigh.
    if (!(*lambda_min < 0.0)) {
        result->status = CertificateResult::Status::kInconclusive;
        result->reason =
            "S + eta D did not factorize, yet lambda_min = " + std::to_string(*lambda_min) +
            " >= 0";
        return;
    }
    result->status = CertificateResult::Status::kNotOptimal;
}

CertificateResult CertifyWithMultipliers(const SparseMatrix& Q, const Eigen::MatrixXd& X, int d,
                                         const std::vector<Eigen::MatrixXd>& lambda,
                                         const CertificateConfig& config) {
    config.Validate();
    const auto start = std::chrono::steady_clock::now();
    CERTISLAM_CHECK(X.cols() == Q.rows() && X.cols() % (d + 1) == 0);
    const int n = static_cast<int>(X.cols()) / (d + 1);
    CERTISLAM_CHECK(static_cast<int>(lambda.size()) == n);
    CertificateResult result;
    const SparseMatrix S = CertificateMatrix(Q, lambda, d);
    CertificateQuantities q;
    q.d = d;
    q.n = n;
    const ObjectiveShare objective = ObjectiveOfColumns(Q, X, 0, Q.cols());
    q.objective = objective.value;
    q.objective_noise = objective.noise;
    for (const auto& block : lambda) q.dual_value += block.trace();
    q.q_norm = NormUpperBound(Q);
    q.gradient_norm = 2.0 * (X * S).norm();
    q.x_norm = X.norm();
    const auto finish = [&] {
        result.seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        return result;
    };
    const bool critical = FirstOrderVerdict(q, config, &result);
    const std::string off_manifold = OffManifold(X, d);
    if (!off_manifold.empty()) {
        result.status = CertificateResult::Status::kInconclusive;
        result.reason = off_manifold;
        return finish();
    }
    if (!critical) return finish();
    const auto pair = Eigenpair(S, result.eta, config, &result);
    SecondOrderVerdict(q, pair ? std::optional<double>(pair->lambda) : std::nullopt, config,
                       MakePsdTest(S, d), &result);
    if (result.status == CertificateResult::Status::kNotOptimal) {
        const EscapeResult escape = EscapeSaddle(Q, X, d, pair->vector, result.gradient_tolerance);
        if (escape.status == EscapeResult::Status::kEscaped) {
            result.escape_descent = escape.cost_before - escape.cost_after;
            result.escape_step = escape.step;
        }
    }
    return finish();
}

}  // namespace certislam::certify
