// One robot's share of the team's second-order finish, without sockets: a Riemannian trust
// region on the whole X (Steihaug-CG on the exact Hessian 2 Proj_X(V S(X)), S = Q - Lambda(X) as
// the certificate builds it), preconditioned by additive Schwarz on overlapping domains. Every
// step needs only neighbour exchanges (the own rows of S read the neighbours' entries at the
// poses the own edges touch; the preconditioner reads and returns entries within a few edges of
// the own poses) and scalar sums over robots; every robot takes the same decisions from the same
// sums (added in team order). RBCD's rounds have a slow linear tail on graphs with stiff
// inter-robot coupling (parking-garage, city10000); this finish converges quadratically there.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <map>
#include <memory>
#include <set>
#include <vector>

#include "certify/pipeline/solver_state.h"
#include "slam/core/loop_closure.h"

namespace certislam::certify {

/// Settings of the finish.
struct TeamFinishConfig {
    double rel_grad_tol = 1e-10;  ///< stop: ||rgrad f|| <= this * max(1, f), > 0
    /// Also stop once the gradient is below this * max(1, f) and stopped halving over three
    /// trust-region steps: the floor doubles resolve on an ill-conditioned graph (the centralised
    /// solver's slam::RbcdConfig::rel_grad_tol). >= rel_grad_tol.
    double floor_rel_grad_tol = 1e-6;
    int max_iterations = 200;       ///< trust-region steps, >= 1
    int max_tcg_iterations = 3000;  ///< Steihaug-CG iterations per step, >= 1
    /// Truncated CG stops at the latest at residual <= this * the gradient tolerance, [0, 1)
    /// (slam::BlockRtrOptions::tcg_residual_floor).
    double tcg_residual_floor = 0.5;
    /// Schwarz domains: the own poses and every neighbour's pose within this many edges of them
    /// (walking through that neighbour's poses). 0: block Jacobi (no exchange for it). In [0, 8].
    int overlap = 1;
    double regulariser = 1e-8;  ///< each domain's factor: Q_D + this * max diag(Q_D) I, > 0

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// A block of lifted entries for one neighbour: exchange `step`'s values at `ids` (r x 4|ids|).
struct FinishVector {
    int to = 0;                     ///< the receiving robot
    std::uint64_t step = 0;         ///< the exchange's index (the same on every robot)
    std::vector<slam::PoseId> ids;  ///< the sender's poses, or the receiver's (a returned share)
    Eigen::MatrixXd blocks;         ///< r x 4|ids|
};

/// One robot's partial sums of reduction `step`, for every robot of the team.
struct FinishSums {
    std::uint64_t step = 0;
    std::vector<double> values;
};

/// Edges for one neighbour's Schwarz domain (sent once, before the first exchange).
struct FinishEdges {
    int to = 0;
    std::vector<slam::PoseId> poses;       ///< the sender's poses in the receiver's domain
    std::vector<slam::LoopClosure> edges;  ///< the sender's edges touching them
};

/// Counters of one robot's finish (the same on every robot but `entries_sent`).
struct TeamFinishProgress {
    int iterations = 0;            ///< trust-region steps taken
    int accepted = 0;              ///< of them accepted
    int tcg_iterations = 0;        ///< Steihaug-CG iterations over all steps
    std::uint64_t exchanges = 0;   ///< neighbour exchanges
    std::uint64_t reductions = 0;  ///< sums over robots
    double entries_sent = 0.0;     ///< doubles this robot sent to neighbours
    double cost = 0.0;             ///< f at the current iterate (team)
    double grad_norm = 0.0;        ///< ||rgrad f|| there (team)
    bool at_floor = false;         ///< converged at floor_rel_grad_tol, not rel_grad_tol
    std::uint64_t dropped = 0;     ///< messages dropped: out of step, repeated, malformed
};

/// One robot's finish: construct, Start(), then hand it every neighbour's FinishEdges,
/// FinishVector and every robot's FinishSums (its own are fed back by the caller as well: Take*
/// returns them with the others), sending what Take* returns, until Done().
class TeamFinish {
  public:
    enum class Status {
        kRunning,
        kConverged,     ///< ||rgrad f|| <= rel_grad_tol * max(1, f)
        kNotConverged,  ///< max_iterations, or the radius collapsed
        /// A robot's entries did not cover the poses another reads, a factor failed, or a sum
        /// was malformed: every robot ends so at the same sum (none waits for the others)
        kInconsistent,
    };

    /// Robot `robot` of `team` (ids, each once, `robot` among them; every robot's sums are
    /// awaited), its block X_own (r x 4n, own index order) and `edges`: every edge touching an
    /// own pose, each once. The neighbours' poses come from the first exchange (every robot's X).
    /// Throws std::invalid_argument on a bad team or config.
    TeamFinish(int robot, std::vector<int> team, const Eigen::MatrixXd& X_own,
               std::vector<slam::LoopClosure> edges, TeamFinishConfig config);
    ~TeamFinish();
    TeamFinish(TeamFinish&&) noexcept;
    TeamFinish& operator=(TeamFinish&&) noexcept;

    /// Queues the setup edges and the first exchange (the own entries of X).
    void Start();
    /// A neighbour's poses in this robot's domain and its edges touching them (FinishEdges).
    void OnEdges(int robot, const std::vector<slam::PoseId>& poses,
                 const std::vector<slam::LoopClosure>& edges);
    /// A neighbour's entries of exchange `step`.
    void OnVector(int robot, std::uint64_t step, const std::vector<slam::PoseId>& ids,
                  const Eigen::MatrixXd& blocks);
    /// A robot's partial sums of reduction `step` (this robot's own included).
    void OnSums(int robot, std::uint64_t step, const std::vector<double>& values);

    /// What to send now (and forget); the sums go to every robot, this one included.
    std::vector<FinishEdges> TakeEdges();
    std::vector<FinishVector> TakeVectors();
    std::vector<FinishSums> TakeSums();

    Status status() const;
    bool Done() const { return status() != Status::kRunning; }
    /// The own block at the current iterate (the finish's result once Done()).
    const Eigen::MatrixXd& Block() const;
    /// The neighbours' poses at the current iterate: those the own edges touch, and each
    /// neighbour's pose 0 (the frame a trajectory is anchored in).
    PoseBlocks NeighbourPoses() const;
    const TeamFinishProgress& Progress() const;
    /// Robots this one exchanges entries with (those its edges reach).
    const std::set<int>& Neighbours() const;

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace certislam::certify
