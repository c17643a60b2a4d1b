// Robust pose-graph optimisation against outlier loop closures: graduated non-convexity with a
// truncated-least-squares cost (GNC-TLS, Yang et al., RA-L 2020), inner solves by RBCD.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "slam/backend/rbcd.h"
#include "slam/core/partition.h"
#include "slam/core/pose_graph.h"

namespace certislam::slam {

/// Settings of SolveGnc.
struct GncConfig {
    /// TLS threshold c on an edge's residual r_e = sqrt(kappa ||Y_j - Y_i R~||^2 + tau ||p_j -
    /// p_i - Y_i t~||^2) (weights excluded): edges with r_e > c cost c^2 and end with weight 0.
    /// r_e^2 of a Gaussian edge is about a chi-square with d(d+1) degrees of freedom times a
    /// constant near 1/2..1, so c = 5 keeps inliers with margin (dpgo's GNC default barc = 5).
    double threshold = 5.0;
    double mu_growth = 1.4;    ///< mu_{k+1} = mu_growth mu_k (Yang et al.: 1.4), > 1
    int max_iterations = 100;  ///< GNC outer iterations, > 0
    /// Stop when every weight is within this of 0 or 1 (the TLS problem is then solved), (0, 0.5).
    double binary_tolerance = 1e-3;
    double keep_weight = 0.5;  ///< an edge is kept (inlier) when its final weight >= this
    /// Treat odometry edges (consecutive keyframes of one robot) as known inliers: the kept graph
    /// then stays connected whatever the loop closures do.
    bool keep_odometry = true;
    /// After GNC, rejected edges are put back one at a time (smallest residual first) and kept
    /// when the re-solved problem has every free kept edge within the threshold; the search stops
    /// after this many rejections in a row (0 = no reinstatement), >= 0.
    int max_reinstatement_failures = 10;
    RbcdConfig rbcd;  ///< inner solver

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// Outcome of SolveGnc.
struct GncResult {
    enum class Status {
        kConverged,      ///< weights became binary
        kNoOutliers,     ///< every residual below the threshold at the least-squares solution
        kMaxIterations,  ///< max_iterations reached first
    };
    Status status = Status::kMaxIterations;
    Eigen::MatrixXd X;            ///< solution of the last weighted problem (rank of X0)
    std::vector<double> weights;  ///< final weight per edge of the input graph, in its order
    std::vector<bool> inlier;     ///< weights[e] >= keep_weight (known inliers always true)
    PoseGraph kept;               ///< the input graph restricted to inliers, weights reset to 1
    int iterations = 0;           ///< GNC outer iterations
    int rbcd_iterations = 0;      ///< RBCD outer iterations over all inner solves
    int reinstated = 0;           ///< rejected edges put back by the reinstatement pass
    double final_mu = 0.0;        ///< mu when stopped
    double seconds = 0.0;         ///< wall time
};

/// Unweighted squared residual r_e^2 of every edge at X (r x (d+1)n, any rank r >= d).
std::vector<double> EdgeSquaredResiduals(const PoseGraph& graph, const Eigen::MatrixXd& X);

/// GNC-TLS from X0: known inliers (is_known_inlier, and odometry when config.keep_odometry) keep
/// weight 1; the others start at 1 with
/// mu_0 = c^2 / (2 max r^2 - c^2) and follow Yang et al.'s TLS weight update (Prop. 4) while mu
/// grows; each weighted problem is solved by SolveRbcd warm-started from the last solution. A
/// reinstatement pass then re-tests each rejected edge against the problem solved with it.
GncResult SolveGnc(const PoseGraph& graph, const Partition& partition, const Eigen::MatrixXd& X0,
                   const GncConfig& config = {});

}  // namespace certislam::slam
