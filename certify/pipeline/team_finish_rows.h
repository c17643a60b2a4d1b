// One robot's algebra in the team's finish (team_finish.h): its rows of S(X) at one iterate, the
// Riemannian gradient and Hessian-vector products on its own columns, and the cost change between
// two iterates, each from the own block and the neighbours' entries at the poses its edges touch.
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <map>
#include <utility>
#include <vector>

#include "certify/distributed/distributed_certificate.h"
#include "certify/pipeline/solver_state.h"
#include "slam/core/loop_closure.h"

namespace certislam::certify {

/// One iterate as a robot holds it.
struct FinishPoint {
    Eigen::MatrixXd X;                            ///< own block, r x 4n
    std::map<slam::PoseId, Eigen::MatrixXd> nbr;  ///< neighbours' poses (r x 4 each)
    LocalCertificateProblem problem;              ///< own rows of S(X)
    Eigen::MatrixXd grad;                         ///< own columns of rgrad f = 2 X S
};

/// Neighbours' entries of one exchange: robot -> (pose ids, r x 4|ids| blocks).
using FinishEntries = std::map<int, std::pair<std::vector<slam::PoseId>, Eigen::MatrixXd>>;

/// The columns of `own` (r x 4n, own index order) at the own poses `ids`, one block each.
Eigen::MatrixXd OwnColumns(const Eigen::MatrixXd& own, const std::vector<slam::PoseId>& ids);

/// The blocks of `by_id` (r x 4 each) as one PoseBlocks, in id order.
PoseBlocks BlocksOf(const std::map<slam::PoseId, Eigen::MatrixXd>& by_id, Eigen::Index rank);

/// Every block of `in` by pose id into `*by_id` (newer replace older).
void StoreEntries(const FinishEntries& in, std::map<slam::PoseId, Eigen::MatrixXd>* by_id);

/// tau >= 0 with ||eta + tau delta||_M = radius, from ||eta||_M^2, <eta, delta>_M, ||delta||_M^2
/// (Steihaug-Toint's step to the trust region's boundary); 0 when delta is 0.
double SteihaugToBoundary(double e_Pe, double e_Pd, double d_Pd, double radius);

class FinishRows {
  public:
    /// Robot `robot` with `n_own` poses and `edges` (every edge touching an own pose, each once).
    FinishRows(int robot, int n_own, std::vector<slam::LoopClosure> edges);

    /// The own rows of S and the gradient at p->X against p->nbr; false when an edge's far end
    /// has no pose there.
    bool Build(FinishPoint* p) const;
    /// The entries of `by_id` at the poses p's rows read (problem.neighbor_ids order); false
    /// when one is missing or of another rank.
    static bool Gather(const FinishPoint& p, const std::map<slam::PoseId, Eigen::MatrixXd>& by_id,
                       Eigen::MatrixXd* out);
    /// Own columns of Hess f(X)[V] = Proj_X(2 V S(X)) from V's own block and neighbour entries.
    static Eigen::MatrixXd Hessian(const FinishPoint& p, const Eigen::MatrixXd& V_own,
                                   const Eigen::MatrixXd& V_nbr);
    /// The own share of f(X+) - f(X) = <X+ - X, (X+ + X) Q> over the own columns, measured
    /// directly (the difference of two rounded costs drowns it near the optimum), and its
    /// rounding bound; (0, 0) when a neighbour pose is missing at either point.
    std::pair<double, double> CostChange(const FinishPoint& at, const FinishPoint& cand) const;
    /// Own poses each neighbour's rows read (those with an edge to it; ascending), by neighbour.
    std::map<int, std::vector<slam::PoseId>> ReadBy() const;
    const std::vector<slam::PoseId>& OwnIds() const { return own_ids_; }
    const std::vector<slam::LoopClosure>& Edges() const { return edges_; }

  private:
    int robot_;
    std::vector<slam::PoseId> own_ids_;
    std::vector<slam::LoopClosure> edges_;
    Eigen::SparseMatrix<double> q_cols_;  ///< Q's own columns: own poses, then local_nbr_
    std::vector<slam::PoseId> local_nbr_;
};

}  // namespace certislam::certify
