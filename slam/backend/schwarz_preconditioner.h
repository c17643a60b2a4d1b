// Overlapping additive Schwarz preconditioner for the multi-robot finish of RBCD: each robot
// solves Q on its own poses plus the poses within a few edges of them.
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <memory>
#include <vector>

#include "slam/backend/rbcd_block.h"
#include "slam/core/partition.h"

namespace certislam::slam {

/// P^{-1} = sum_k R_k^T (R_k Q_s R_k^T)^{-1} R_k with Q_s = Q + shift I, applied to the
/// (d+1)n-long rows of X-shaped matrices. R_k selects robot k's extended domain: its own poses
/// and every pose within `overlap` edges of them. overlap 0 is block Jacobi (each robot's own
/// Q_aa). Block Jacobi misses the stiff inter-robot loop closures, which an overlap of one or
/// two edges takes in (a coarse level on each robot's rigid motions helps far less).
/// Every R_k Q_s R_k^T is a principal submatrix of Q_s (PSD plus shift I) and the domains cover
/// every pose, so P^{-1} is symmetric positive definite; and P^{-1} dominates block Jacobi's
/// inverse (P <= P_BJ), so a trust-region radius measured in block Jacobi's norm stays valid
/// after an escalation (it can only be more permissive).
///
/// Distributed form (not run over a network here): robot k factorises R_k Q_s R_k^T once. With
/// overlap 1 its domain is its own poses and its neighbours' public poses (those its edges
/// touch): it needs the Q entries among those (sent once by their owners, again when an edge is
/// added), and an application needs the vector at those poses (one exchange between neighbours,
/// as a Hessian-vector product does) and returns its contribution there (a second exchange).
/// With overlap 2 the domain also holds poses one edge further, private poses of neighbours and
/// possibly poses of robots two hops away in the robot graph: the same two exchanges, with
/// those robots too.
///
/// The overlap costs: each robot's domain, and so each application, grows where block Jacobi
/// already needs few iterations. So the preconditioner starts as block Jacobi and escalates to
/// its largest overlap once a conjugate-gradient run needs more than a threshold.
class SchwarzPreconditioner {
  public:
    /// Q the connection Laplacian ((d+1)n square, borrowed for the object's lifetime); every
    /// robot of `partition` has at least one pose; shift = regulariser * max diag(Q) (> 0); the
    /// overlap starts at 0 and becomes max_overlap (>= 0) at the first ReportCgIterations above
    /// escalate_after (> 0).
    SchwarzPreconditioner(const Eigen::SparseMatrix<double>& Q, int d, const Partition& partition,
                          int max_overlap, int escalate_after, double regulariser);

    /// P^{-1} B for B of (d+1)n rows (one right-hand side per column).
    Eigen::MatrixXd Solve(const Eigen::MatrixXd& B) const;

    /// Iterations the next conjugate-gradient run should be allowed, given its own cap: while
    /// an escalation is still possible, escalate_after + 1 (a truncated Steihaug iterate is a
    /// valid step, and block Jacobi could otherwise spend the whole cap first).
    int IterationCap(int cap) const;

    /// Told how many iterations the last conjugate-gradient run with this preconditioner took;
    /// more than escalate_after: refactorises with max_overlap (call between two runs only). A
    /// factorisation that fails keeps the current preconditioner.
    void ReportCgIterations(int iterations);

    /// The overlap in use.
    int overlap() const { return overlap_; }

    /// Poses of robot k's extended domain (ascending global ids).
    const std::vector<int>& Domain(int k) const { return domains_[k]; }

  private:
    // Factorises every robot's domain at `overlap`; false (and nothing changed) on failure.
    bool Build(int overlap);

    const Eigen::SparseMatrix<double>* Q_;
    int d_;
    Partition partition_;
    int max_overlap_;
    int escalate_after_;
    double shift_;
    int overlap_ = -1;
    std::vector<std::vector<int>> domains_;
    std::vector<std::unique_ptr<BlockFactor>> factors_;
};

}  // namespace certislam::slam
