// Riemannian block coordinate descent (RBCD / RBCD++, Tian et al., T-RO 2021) on the rank-r
// relaxation of pose-graph optimisation, every robot's agent in one process (rbcd_agent.h holds
// the settings, the cost and one robot's agent).
#pragma once

#include <Eigen/Core>
#include <functional>

#include "slam/backend/rbcd_agent.h"
#include "slam/core/partition.h"
#include "slam/core/pose_graph.h"

namespace certislam::slam {

/// Reported after every outer iteration through the optional progress callback.
struct RbcdProgress {
    int iteration = 0;       ///< outer iterations done
    double cost = 0.0;       ///< f(X) = tr(X Q X^T)
    double grad_norm = 0.0;  ///< ||rgrad f(X)||_F
    double seconds = 0.0;    ///< since the solve started
};

/// Outcome of SolveRbcd.
struct RbcdResult {
    enum class Status {
        kConverged,      ///< ||rgrad|| <= rel_grad_tol * max(1, f)
        kMaxIterations,  ///< max_iterations reached first
        kMaxTime,        ///< max_seconds reached first
        kStalled,        ///< the cost stopped decreasing before the gradient tolerance was met
        kCostConverged,  ///< f decreased by <= rel_cost_decrease_tol over cost_window iterations
    };
    Status status = Status::kMaxIterations;
    Eigen::MatrixXd X;              ///< r x (d+1)n solution (rank r = X0.rows())
    double cost = 0.0;              ///< tr(X Q X^T) (SE-Sync objective of the lifted X, no 1/2)
    double grad_norm = 0.0;         ///< ||rgrad f(X)||_F at the returned X
    int iterations = 0;             ///< outer iterations
    int block_updates = 0;          ///< block (robot) updates over all iterations
    int rtr_iterations = 0;         ///< trust-region steps over all block updates
    int restarts = 0;               ///< adaptive restarts of the acceleration
    int polish_rtr_iterations = 0;  ///< trust-region steps of the distributed finish
    double seconds = 0.0;           ///< wall-clock time of the solve
};

/// Solves min f(X) over the product manifold from X0 (r x (d+1)n, a point on the manifold) by
/// RBCD with one block per robot of `partition`. With one robot this is a centralised Riemannian
/// trust-region method (SE-Sync's solver on the lifted variable).
RbcdResult SolveRbcd(const PoseGraph& graph, const Partition& partition, const Eigen::MatrixXd& X0,
                     const RbcdConfig& config,
                     const std::function<void(const RbcdProgress&)>& progress = {});

}  // namespace certislam::slam
