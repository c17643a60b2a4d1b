// The local-search baseline: Levenberg-Marquardt (Ceres) on SE(d) poses, minimising exactly the
// SE-Sync objective, so its cost compares directly with f* and with the certified solution.
#pragma once

#include <string>

#include "slam/core/pose_graph.h"

namespace certislam::slam {

/// Settings of SolveLm.
struct LmConfig {
    int max_iterations = 500;            ///< LM iterations, > 0
    double function_tolerance = 1e-12;   ///< Ceres relative cost change to stop, > 0
    double gradient_tolerance = 1e-12;   ///< Ceres max-norm gradient (relative) to stop, > 0
    double parameter_tolerance = 1e-12;  ///< Ceres relative step size to stop, > 0
    int num_threads = 1;                 ///< Ceres Jacobian threads, >= 1

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// Outcome of SolveLm.
struct LmResult {
    enum class Status {
        kConverged,      ///< a Ceres tolerance was met
        kNoConvergence,  ///< max_iterations reached first
        kFailed,         ///< Ceres reported a failure (numerical, invalid problem)
    };
    Status status = Status::kFailed;
    PoseMatrix poses;           ///< d x (d+1)n, blocks [R_g t_g], pose 0 held fixed at the guess
    double initial_cost = 0.0;  ///< f at the initial guess (SE-Sync objective, no 1/2)
    double cost = 0.0;          ///< f at the solution
    int iterations = 0;         ///< LM iterations (successful and unsuccessful steps)
    double seconds = 0.0;       ///< Ceres wall time
    std::string message;        ///< Ceres' termination message
};

/// Minimises f(R, t) = sum w (kappa ||R_j - R_i R~||_F^2 + tau ||t_j - t_i - R_i t~||^2) by
/// Levenberg-Marquardt from `initial` (d x (d+1)n); rotations as unit quaternions on Ceres'
/// quaternion manifold (3D) or angles (2D); pose 0 fixed (gauge).
LmResult SolveLm(const PoseGraph& graph, const PoseMatrix& initial, const LmConfig& config = {});

}  // namespace certislam::slam
