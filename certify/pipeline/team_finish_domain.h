// The Schwarz domain of one robot in the team's finish (team_finish.h): its own poses and the
// neighbours' poses within a few edges of them, and the factor of Q on that domain.
#pragma once

#include <Eigen/Core>
#include <map>
#include <memory>
#include <set>
#include <vector>

#include "slam/backend/rbcd_block.h"
#include "slam/core/loop_closure.h"

namespace certislam::certify {

/// P_k^{-1} = R_k^T (R_k Q R_k^T + shift I)^{-1} R_k of additive Schwarz (SchwarzPreconditioner
/// in distributed form): R_k selects the own poses and, of each neighbour j, its poses within
/// `overlap` edges of the own ones walking through j's poses. Each robot computes which of its
/// poses lie in a neighbour's domain (OwnPosesIn) and sends it the edges touching them (EdgesFor),
/// so the domain's matrix is a principal submatrix of Q (edges leaving the domain add to the
/// diagonal only); a pose of a third robot stays out of the domain.
class FinishDomain {
  public:
    /// Robot `robot` with `n_own` poses; `edges`: every edge touching an own pose, each once.
    FinishDomain(int robot, int n_own, const std::vector<slam::LoopClosure>& edges, int overlap,
                 double regulariser);
    ~FinishDomain();

    /// Own poses in neighbour j's domain (ascending; empty at overlap 0).
    const std::vector<slam::PoseId>& OwnPosesIn(int j) const;
    /// The own edges touching OwnPosesIn(j): what j needs of Q for its domain.
    std::vector<slam::LoopClosure> EdgesFor(int j) const;
    /// Neighbour j's poses in this robot's domain and the edges touching them.
    void Add(int j, const std::vector<slam::PoseId>& poses,
             const std::vector<slam::LoopClosure>& edges);
    /// Builds the domain's factor from the own edges and those added; false when CHOLMOD fails.
    bool Factorize();
    /// Other robots' poses of the domain (ascending), after Factorize.
    const std::vector<slam::PoseId>& Others() const { return others_; }
    /// (Q_D + shift I)^{-1} applied to the rows of B (r x 4|D|: own poses, then Others()).
    Eigen::MatrixXd Solve(const Eigen::MatrixXd& B) const;
    /// The domain's solve of r (own columns) with the neighbours' entries `by_id` at Others():
    /// the own part in *z_own, each neighbour's part in (*ids)[j], (*blocks)[j] (every key of
    /// *ids gets a block), and <r_D, z_D> over the domain in *rz; false when an entry is missing
    /// or of another rank.
    bool Solve(const Eigen::MatrixXd& r, const std::map<slam::PoseId, Eigen::MatrixXd>& by_id,
               Eigen::MatrixXd* z_own, std::map<int, std::vector<slam::PoseId>>* ids,
               std::map<int, Eigen::MatrixXd>* blocks, double* rz) const;
    /// Adds the neighbours' returned parts at own poses (messages of (ids, r x 4|ids|)) to z;
    /// false when one names a pose that is not own or has another rank.
    bool AddReturned(const std::map<int, std::pair<std::vector<slam::PoseId>, Eigen::MatrixXd>>& in,
                     Eigen::MatrixXd* z) const;

  private:
    int robot_;
    int n_own_;
    double regulariser_;
    std::vector<slam::LoopClosure> edges_;  ///< own, then added (each pair once)
    std::set<std::pair<slam::PoseId, slam::PoseId>> known_;
    std::map<int, std::vector<slam::PoseId>> own_in_;  ///< OwnPosesIn by neighbour
    std::set<slam::PoseId> added_;                     ///< neighbours' poses in the domain
    std::vector<slam::PoseId> others_;
    std::unique_ptr<slam::BlockFactor> factor_;
};

}  // namespace certislam::certify
