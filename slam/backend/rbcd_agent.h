// One robot's share of RBCD (Tian et al., T-RO 2021, Alg. 1, line 4) with plain data in and out,
// the RBCD settings and the lifted cost f(X) = tr(X Q X^T), X = [Y_1 p_1 ... Y_n p_n], with its
// Riemannian gradient.
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <memory>
#include <vector>

#include "slam/core/partition.h"
#include "slam/core/pose_graph.h"

namespace certislam::slam {

/// Settings of the RBCD solver. Gradient tolerances are relative to the problem's scale:
/// converged when ||rgrad f(X)||_F <= rel_grad_tol * max(1, f(X)) (MATH.md: absolute tolerances
/// stop parking-garage 2.4 % above f*).
struct RbcdConfig {
    double rel_grad_tol = 1e-6;          ///< global stop: ||rgrad|| <= this * max(1, f), > 0
    double local_tol_factor = 0.1;       ///< block stop tolerance = this * global tolerance, (0, 1]
    double block_grad_reduction = 1e-2;  ///< block stop when its gradient dropped by this, (0, 1)
    int block_max_rtr_iterations = 5;    ///< trust-region steps per block update, >= 1
    int max_tcg_iterations = 100;        ///< Steihaug-CG iterations per trust-region step, >= 1
    /// Truncated CG stops at the latest when its residual is <= this * the trust region's
    /// gradient tolerance (Manopt's r0 min(r0, 0.1) alone asks for more accuracy than the
    /// stopping test needs once the gradient is small). 0: Manopt's rule alone, so a solve ends
    /// far below its tolerance. certify::StaircaseConfig (`certislam solve` without --robust) and
    /// certify::SolverConfig (the robots' solver actors) set 0.5; the GNC inner solves of
    /// --robust keep 0. In [0, 1).
    double tcg_residual_floor = 0.0;
    int max_iterations = 2000;   ///< outer RBCD iterations, >= 1
    double max_seconds = 600.0;  ///< wall-clock limit, > 0
    bool acceleration = true;    ///< Nesterov acceleration with adaptive restart (RBCD++)
    bool greedy = false;  ///< true: update only the colour class with the largest gradient per
                          ///< iteration; false: every colour class in turn (one sweep)
    double precon_regulariser = 1e-8;  ///< Cholesky of Q_aa + this * max diag(Q_aa) I, > 0
    /// Precondition each block's truncated CG with the Cholesky of its exact Hessian matrix
    /// S_aa = Q_aa - Lambda_a(X) (+ a small shift), refactorised per trust-region iterate;
    /// false: Q_aa alone (the factor above). Off by default: it is not faster on every graph,
    /// and it moves a 2-robot team's result beyond 1e-5 of the central one.
    bool hessian_preconditioner = false;
    /// Each block update eliminates its translations exactly (SE-Sync's reduced problem): the
    /// trust region runs on the rotations with the Schur complement of Q_TT, and the Q_aa
    /// preconditioner becomes the inverse of the reduced Euclidean Hessian (up to its regulariser
    /// and the factor 2; not of the Riemannian Hessian, which adds the curvature term). false: the
    /// explicit problem over rotations and translations.
    bool eliminate_translations = true;
    /// Multi-robot: after this many RBCD iterations without convergence (or an earlier stall),
    /// finish with second-order steps: a trust region on the whole X whose Hessian-vector
    /// products need neighbours' entries (as RBCD's linear terms do) and, with
    /// eliminate_translations (the default), a global translation solve (below), and whose
    /// preconditioner is each robot's own factor (block Jacobi, overlapping Schwarz once CG
    /// needs many iterations: polish_overlap below); inner products are sums of one scalar per
    /// robot. Block coordinate descent alone has a slow linear tail on
    /// graphs with strong inter-robot coupling (parking-garage). With eliminate_translations
    /// the finish eliminates the translations of the whole graph: each Hessian-vector product
    /// then also needs Q_TT^{-1} (the scalar translation Laplacian) applied to r vectors, done
    /// here by one global sparse Cholesky. On a network that would be an all-gather or an
    /// inner distributed CG, far slower than one Cholesky solve, so this in-process finish is
    /// distributed except for that solve. 0 disables; >= 0.
    int polish_after_iterations = 5;
    /// The finish's preconditioner (slam/schwarz_preconditioner.h): block Jacobi (each robot's
    /// own Cholesky of Q_aa) until one truncated CG needs more than polish_escalate_after
    /// iterations, then overlapping additive Schwarz, each robot's domain its own poses and those
    /// within polish_overlap edges of them (wider overlap needs fewer CG iterations but grows
    /// every domain's factor). In [0, 8]; 0: block Jacobi throughout.
    int polish_overlap = 2;
    /// Truncated-CG iterations after which the finish's preconditioner escalates to
    /// polish_overlap (a CG run is cut there while it can still escalate), >= 1.
    int polish_escalate_after = 50;
    int polish_max_rtr_iterations = 300;  ///< trust-region steps of the finish, >= 1
    /// Steihaug-CG iterations per step of the finish, >= 1 (high: with block Jacobi alone an
    /// ill-conditioned graph needs thousands).
    int polish_max_tcg_iterations = 2000;
    /// Second stop, for the slow linear tail of block coordinate descent: f fell by at most
    /// this * max(1, f) over the last `cost_window` iterations (the remaining gap is then far
    /// below 1e-6 f unless the rate is slower than 1 - 1e-4 per iteration). >= 0; 0 disables.
    double rel_cost_decrease_tol = 1e-10;
    int cost_window = 10;  ///< iterations the decrease is measured over, >= 1

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// f(X) = tr(X Q X^T).
double LiftedCost(const Eigen::SparseMatrix<double>& Q, const Eigen::MatrixXd& X);

/// Riemannian gradient of f at X: the projection of 2 X Q onto the tangent space of the product
/// of St(d, r) (rotation blocks) and R^r (translations).
Eigen::MatrixXd RiemannianGradient(const Eigen::SparseMatrix<double>& Q, const Eigen::MatrixXd& X,
                                   int d);

/// What one RbcdAgent::Update did.
struct RbcdAgentStatus {
    enum class Status {
        kImproved,   ///< the block's cost decreased
        kConverged,  ///< the block gradient was already below the tolerance: nothing done
        kNoProgress  ///< no trust-region step was accepted
    };
    Status status = Status::kConverged;
    double cost_before = 0.0;       ///< block cost before (up to a constant)
    double cost_after = 0.0;        ///< block cost after
    double grad_norm_before = 0.0;  ///< block Riemannian gradient norm before
    double grad_norm_after = 0.0;   ///< block Riemannian gradient norm after
    int rtr_iterations = 0;         ///< trust-region steps taken
};

/// One robot's share of RBCD with plain data in and out (dpgo's agent without networking): it
/// owns its poses' block X_a, receives its neighbours' public poses, and publishes its own.
class RbcdAgent {
  public:
    /// `graph` must hold every edge touching the robot's poses (more is fine), global indices;
    /// `rank` is r.
    RbcdAgent(const PoseGraph& graph, const Partition& partition, int robot, int rank,
              const RbcdConfig& config);
    /// Same from the global connection Laplacian Q (only its columns of this robot are read).
    RbcdAgent(const Eigen::SparseMatrix<double>& Q, int d, const Partition& partition, int robot,
              int rank, const RbcdConfig& config);
    ~RbcdAgent();
    RbcdAgent(RbcdAgent&&) noexcept;
    RbcdAgent& operator=(RbcdAgent&&) noexcept;

    /// This agent's robot id.
    int robot() const;
    /// Global indices of other robots' poses this robot's edges touch (ascending).
    const std::vector<int>& NeighborPoseIds() const;
    /// Global indices of own poses that other robots' edges touch (ascending).
    const std::vector<int>& PublicPoseIds() const;
    /// Sets the robot's own block, r x (d+1) * partition.size(robot).
    void SetBlock(const Eigen::MatrixXd& X_a);
    /// The robot's own block.
    const Eigen::MatrixXd& Block() const;
    /// Sets neighbours' poses: r x (d+1)|NeighborPoseIds()|, blocks in NeighborPoseIds() order.
    void SetNeighborPoses(const Eigen::MatrixXd& blocks);
    /// Own public poses, r x (d+1)|PublicPoseIds()|, blocks in PublicPoseIds() order.
    Eigen::MatrixXd PublicPoses() const;
    /// Riemannian gradient norm of the block given the current neighbour poses.
    double BlockGradNorm() const;
    /// A few preconditioned trust-region steps on the block (RBCD Alg. 1, line 4) until the
    /// block gradient is <= grad_tol or dropped by config.block_grad_reduction.
    RbcdAgentStatus Update(double grad_tol);

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace certislam::slam
