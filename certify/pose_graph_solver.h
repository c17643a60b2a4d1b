// One call from a pose graph to certified SE(d) poses: initialisation, solver (RBCD staircase or
// the Levenberg-Marquardt baseline), optional GNC-TLS, rounding and the certificate's verdict.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <string>

#include "certify/certificate.h"
#include "certify/staircase.h"
#include "slam/backend/gnc.h"
#include "slam/backend/lm_baseline.h"
#include "slam/core/pose_graph.h"

namespace certislam::certify {

/// Settings of SolvePoseGraph (`certislam solve`).
struct PoseGraphSolverConfig {
    enum class Method {
        kRbcd,  ///< chordal initialisation, RBCD with the Riemannian staircase until certified
        kLm,    ///< Levenberg-Marquardt from odometry; the certificate judges where it stopped
    };
    Method method = Method::kRbcd;
    /// Robots: contiguous index blocks of the poses (dpgo's convention), 1 <= robots <= n; 0 takes
    /// the graph's own robots from `graph.ids` (multi-robot files).
    int robots = 1;
    int rank = 0;               ///< starting rank r of the relaxation; 0 means d; else >= d
    bool robust = false;        ///< GNC-TLS first, then certify the problem on the kept edges
    StaircaseConfig staircase;  ///< RBCD, certificate and escape settings
    slam::LmConfig lm;          ///< LM baseline settings
    slam::GncConfig gnc;        ///< robust mode settings

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// What SolvePoseGraph found.
struct PoseGraphSolverResult {
    enum class Status {
        kCertified,     ///< the certificate proves the rounded poses globally optimal
        kNotCertified,  ///< critical point with a negative certificate eigenvalue (e.g. LM)
        kNoVerdict,     ///< not critical enough to judge, or the eigensolver failed
    };
    Status status = Status::kNoVerdict;
    slam::PoseMatrix poses;  ///< d x (d+1)n rounded estimate, blocks [R_g t_g]
    double cost = 0.0;       ///< SE-Sync objective of `poses` on the solved graph (no 1/2)
    /// cost - (tr(Lambda) - eta d n): an upper bound of cost - f*; meaningful when certified.
    double suboptimality_bound = 0.0;
    CertificateResult certificate;  ///< the last certificate
    int rank = 0;                   ///< final relaxation rank
    int iterations = 0;             ///< RBCD outer iterations (all rungs) or LM iterations
    int escapes = 0;                ///< saddle escapes of the staircase
    int edges_used = 0;             ///< edges of the solved graph (kept edges in robust mode)
    int gnc_iterations = 0;         ///< GNC outer iterations (robust mode)
    slam::PoseGraph solved_graph;   ///< the graph certified (the input, or its GNC inliers)
    double seconds = 0.0;           ///< initialisation + solve + rounding + certificate
};

/// Progress of a long solve: a stage name ("chordal", "gnc", "rbcd", "certify", "escape",
/// "lm"), the current cost, gradient norm and seconds since the start.
using PoseGraphSolverProgress = std::function<void(const std::string& stage, int rank, double cost,
                                                   double grad_norm, double seconds)>;

/// Solves `graph` (a connected pose graph) as configured. Throws std::invalid_argument on a bad
/// configuration (robots > n, rank < d, ...).
PoseGraphSolverResult SolvePoseGraph(const slam::PoseGraph& graph,
                                     const PoseGraphSolverConfig& config = {},
                                     const PoseGraphSolverProgress& progress = {});

}  // namespace certislam::certify
