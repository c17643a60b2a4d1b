// The Riemannian staircase: RBCD at rank r, certify, escape to rank r + 1 along the certificate's
// eigenvector, until certified (SE-Sync Alg. 2; DCORA's distributed staircase).
#pragma once

#include <Eigen/Core>
#include <functional>
#include <string>
#include <vector>

#include "certify/certificate.h"
#include "certify/saddle_escape.h"
#include "slam/backend/rbcd.h"
#include "slam/core/partition.h"
#include "slam/core/pose_graph.h"

namespace certislam::certify {

/// Settings of SolveCertified.
struct StaircaseConfig {
    /// Solver at every rank; truncated CG stops at half the gradient tolerance at the latest.
    slam::RbcdConfig rbcd = [] {
        slam::RbcdConfig c;
        c.tcg_residual_floor = 0.5;
        return c;
    }();
    CertificateConfig certificate;  ///< verdict at every rank
    EscapeConfig escape;            ///< line search of each escape
    int max_rank = 10;              ///< give up above this rank, >= the rank of X0
    /// RBCD reruns from the same point (iteration budget renewed) when the certificate finds it
    /// not critical enough, >= 0.
    int max_resolves = 1;

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// One rung of the staircase, for the report.
struct StaircaseLevel {
    int rank = 0;             ///< r of this rung
    int rbcd_iterations = 0;  ///< outer RBCD iterations at this rung
    double cost = 0.0;        ///< f(X) after RBCD
    double grad_norm = 0.0;   ///< ||grad f|| after RBCD
    CertificateResult::Status verdict = CertificateResult::Status::kNotCritical;
    double lambda_min = 0.0;       ///< certificate's smallest eigenvalue
    double solve_seconds = 0.0;    ///< RBCD time
    double certify_seconds = 0.0;  ///< certificate time
};

/// Reported at each stage through the optional callback (a progress line for long runs).
struct StaircaseProgress {
    std::string stage;        ///< "rbcd" (each RBCD iteration), "solve", "certify" or "escape"
    int rank = 0;             ///< current r
    double cost = 0.0;        ///< current f(X)
    double grad_norm = 0.0;   ///< current ||grad f||
    double lambda_min = 0.0;  ///< last certificate's lambda_min (0 before the first)
    double seconds = 0.0;     ///< since SolveCertified started
};

/// Outcome of SolveCertified.
struct StaircaseResult {
    enum class Status {
        kCertified,          ///< the final X is certified globally optimal for the relaxation
        kMaxRank,            ///< still not certified at max_rank
        kNotCritical,        ///< RBCD did not reach the certificate's first-order tolerance
        kEigensolverFailed,  ///< verdict "not certified" but no eigenvector to escape along
        kEscapeFailed,       ///< no escape step decreased the cost
    };
    Status status = Status::kNotCritical;
    Eigen::MatrixXd X;                   ///< final r x (d+1)n iterate
    int rank = 0;                        ///< final r
    CertificateResult certificate;       ///< the last certificate
    std::vector<StaircaseLevel> levels;  ///< one per RBCD run
    int iterations = 0;                  ///< RBCD outer iterations, all rungs
    int escapes = 0;                     ///< successful saddle escapes
    double solve_seconds = 0.0;          ///< RBCD time, all rungs
    double certify_seconds = 0.0;        ///< certificate time, all rungs
    double seconds = 0.0;                ///< total wall time
};

/// Loops SolveRbcd -> Certify -> EscapeSaddle from X0 (r0 x (d+1)n on the manifold) until the
/// certificate holds or the rank exceeds config.max_rank.
StaircaseResult SolveCertified(const slam::PoseGraph& graph, const slam::Partition& partition,
                               const Eigen::MatrixXd& X0, const StaircaseConfig& config = {},
                               const std::function<void(const StaircaseProgress&)>& progress = {});

}  // namespace certislam::certify
