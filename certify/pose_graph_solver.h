// One call from a pose graph to certified SE(d) poses: initialisation, solver (RBCD staircase or
// the Levenberg-Marquardt baseline), optional GNC-TLS, rounding and the certificate's verdict.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <string>
#include <vector>

#include "certify/certificate.h"
#include "certify/local_search.h"
#include "certify/staircase.h"
#include "slam/backend/gnc.h"
#include "slam/backend/lm_baseline.h"
#include "slam/core/pose_graph.h"

namespace certislam::certify {

/// Settings of SolvePoseGraph (`certislam solve`).
struct PoseGraphSolverConfig {
    enum class Method {
        kRbcd,  ///< chordal initialisation, RBCD with the Riemannian staircase until certified
        kLm,    ///< Levenberg-Marquardt from odometry, polished on f, then certified or refused
    };
    Method method = Method::kRbcd;
    /// Robots: contiguous index blocks of the poses (dpgo's convention), 1 <= robots <= n; 0 takes
    /// the graph's own robots from `graph.ids` (multi-robot files).
    int robots = 1;
    int rank = 0;               ///< starting rank r of the relaxation; 0 means d; else >= d
    bool robust = false;        ///< GNC-TLS first, then certify the problem on the kept edges
    StaircaseConfig staircase;  ///< RBCD, certificate and escape settings
    slam::LmConfig lm;          ///< LM baseline settings
    /// Polish of the LM result on f at rank d (its certificate settings: staircase.certificate).
    slam::RbcdConfig lm_polish = LocalSearchPolishConfig{}.rbcd;
    slam::GncConfig gnc;  ///< robust mode settings

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// What SolvePoseGraph found. The bound fields are zero unless has_bound (proven).
struct PoseGraphSolverResult {
    /// The certificate's verdict on the reported poses (VerdictName spells it).
    using Status = CertificateResult::Status;
    Status status = Status::kInconclusive;
    std::string reason;                ///< kInconclusive: why
    slam::PoseMatrix poses;            ///< d x (d+1)n rounded estimate, blocks [R_g t_g]
    double cost = 0.0;                 ///< objective f of `poses` on the solved graph (no 1/2)
    bool has_bound = false;            ///< the three bounds below are proven (S + eta D PSD)
    double lower_bound = 0.0;          ///< f* >= this (the certificate's)
    double suboptimality_bound = 0.0;  ///< cost - lower_bound >= cost - f*
    double relative_suboptimality_bound = 0.0;  ///< suboptimality_bound / cost
    CertificateResult certificate;              ///< the last certificate (of the lifted X)
    int rank = 0;                               ///< final relaxation rank
    int iterations = 0;               ///< RBCD outer iterations (all rungs) or LM iterations
    int escapes = 0;                  ///< saddle escapes of the staircase
    double local_search_cost = 0.0;   ///< --method lm: f where LM stopped, before the polish
    int polish_iterations = 0;        ///< --method lm: RBCD iterations of the polish
    int edges_used = 0;               ///< edges of the solved graph (kept edges in robust mode)
    int gnc_iterations = 0;           ///< GNC outer iterations (robust mode)
    int gnc_reinstated = 0;           ///< rejected edges GNC's reinstatement pass put back
    std::vector<int> rejected_edges;  ///< robust mode: 0-based input order of the rejected edges
    slam::PoseGraph solved_graph;     ///< the graph certified (the input, or its GNC inliers)
    double seconds = 0.0;             ///< initialisation + solve + rounding + certificate
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
