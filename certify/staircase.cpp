// SolveCertified: the staircase loop (SE-Sync Alg. 2) over SolveRbcd, Certify and EscapeSaddle.
#include "certify/staircase.h"

#include <algorithm>
#include <chrono>
#include <stdexcept>

#include "slam/backend/connection_laplacian.h"

namespace certislam::certify {
namespace {

using Clock = std::chrono::steady_clock;

double Since(Clock::time_point start) {
    return std::chrono::duration<double>(Clock::now() - start).count();
}

StaircaseResult::Status FromVerdict(CertificateResult::Status s) {
    switch (s) {
        case CertificateResult::Status::kCertified:
            return StaircaseResult::Status::kCertified;
        case CertificateResult::Status::kNotOptimal:
            return StaircaseResult::Status::kMaxRank;
        case CertificateResult::Status::kNotCritical:
            return StaircaseResult::Status::kNotCritical;
        case CertificateResult::Status::kInconclusive:
            break;
    }
    return StaircaseResult::Status::kInconclusive;
}

/// Records the rung just certified in `result` (its verdict, totals and status).
void AddLevel(StaircaseLevel* level, StaircaseResult* result) {
    level->verdict = result->certificate.status;
    level->lambda_min = result->certificate.lambda_min;
    level->certify_seconds = result->certificate.seconds;
    result->levels.push_back(*level);
    result->iterations += level->rbcd_iterations;
    result->solve_seconds += level->solve_seconds;
    result->certify_seconds += level->certify_seconds;
    result->status = FromVerdict(result->certificate.status);
}

}  // namespace

void StaircaseConfig::Validate() const {
    rbcd.Validate();
    certificate.Validate();
    escape.Validate();
    if (max_rank < 2) {
        throw std::invalid_argument("StaircaseConfig.max_rank = " + std::to_string(max_rank) +
                                    ": must be >= 2 and >= the rank of X0");
    }
    if (max_resolves < 0) {
        throw std::invalid_argument(
            "StaircaseConfig.max_resolves = " + std::to_string(max_resolves) + ": must be >= 0");
    }
    if (!(resolve_tolerance_factor > 0.0 && resolve_tolerance_factor <= 1.0)) {
        throw std::invalid_argument("StaircaseConfig.resolve_tolerance_factor = " +
                                    std::to_string(resolve_tolerance_factor) +
                                    ": must be in (0, 1]");
    }
}

StaircaseResult SolveCertified(const slam::PoseGraph& graph, const slam::Partition& partition,
                               const Eigen::MatrixXd& X0, const StaircaseConfig& config,
                               const std::function<void(const StaircaseProgress&)>& progress) {
    config.Validate();
    if (X0.rows() > config.max_rank) {
        throw std::invalid_argument(
            "StaircaseConfig.max_rank = " + std::to_string(config.max_rank) +
            ": must be >= the rank of X0 (" + std::to_string(X0.rows()) + ")");
    }
    const auto start = Clock::now();
    const int d = graph.d;
    const Eigen::SparseMatrix<double> Q = slam::ConnectionLaplacian(graph);
    StaircaseResult result;
    result.X = X0;
    int resolves = 0;
    slam::RbcdConfig rbcd = config.rbcd;  // tightened by each rerun at one rank
    auto report = [&](const char* stage, double cost, double grad) {
        if (!progress) return;
        progress({stage, static_cast<int>(result.X.rows()), cost, grad,
                  result.certificate.lambda_min, Since(start)});
    };
    while (true) {
        StaircaseLevel level;
        level.rank = static_cast<int>(result.X.rows());
        const slam::RbcdResult solved =
            slam::SolveRbcd(graph, partition, result.X, rbcd, [&](const slam::RbcdProgress& p) {
                if (progress) {
                    progress({"rbcd", level.rank, p.cost, p.grad_norm,
                              result.certificate.lambda_min, Since(start)});
                }
            });
        result.X = solved.X;
        level.rbcd_iterations = solved.iterations;
        level.cost = solved.cost;
        level.grad_norm = solved.grad_norm;
        level.solve_seconds = solved.seconds;
        report("solve", solved.cost, solved.grad_norm);
        result.certificate = Certify(Q, result.X, d, config.certificate);
        AddLevel(&level, &result);
        report("certify", result.certificate.objective, result.certificate.gradient_norm);
        const auto verdict = result.certificate.status;
        if ((verdict == CertificateResult::Status::kNotCritical ||
             verdict == CertificateResult::Status::kInconclusive) &&
            resolves++ < config.max_resolves) {
            // RBCD stopped short (stall, budget, or too loose for a tight bound): rerun from
            // here with a tighter tolerance.
            rbcd.rel_grad_tol *= config.resolve_tolerance_factor;
            continue;
        }
        if (result.certificate.status != CertificateResult::Status::kNotOptimal) break;
        if (result.X.rows() + 1 > config.max_rank) break;
        const double rbcd_tol =
            config.rbcd.rel_grad_tol * std::max(1.0, result.certificate.objective);
        const EscapeResult escape =
            EscapeSaddle(Q, result.X, d, result.certificate.eigenvector, rbcd_tol, config.escape);
        if (escape.status != EscapeResult::Status::kEscaped) {
            result.status = StaircaseResult::Status::kEscapeFailed;
            break;
        }
        result.X = escape.X;
        rbcd.rel_grad_tol = config.rbcd.rel_grad_tol;
        ++result.escapes;
        report("escape", escape.cost_after, escape.gradient_norm);
    }
    result.rank = static_cast<int>(result.X.rows());
    result.seconds = Since(start);
    return result;
}

}  // namespace certislam::certify
