// A robot's block update over an overlapping domain (multiplicative Schwarz, as ROBO's
// overlapping blocks): its own poses and the poses of later-sweeping neighbours within a few
// edges of them are optimised together against every other pose held fixed (the domain's share
// of f falls as in RBCD). The neighbours start their own sweep of the round from the poses
// proposed here (TeamRounds applies them), which carries the coupling across the robots' boundary
// and cuts the rounds. f of the whole round is not guaranteed to fall: a robot sweeping in
// between, or one of the same colour next to the same poses, sees their values before the
// proposal; the rounds' adaptive restart catches a round whose f rose.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <optional>
#include <set>
#include <vector>

#include "certify/pipeline/solver_state.h"
#include "certify/pipeline/team_rounds.h"
#include "slam/backend/rbcd_agent.h"
#include "slam/core/loop_closure.h"

namespace certislam::certify {

/// One robot's overlapping block update (plain data in and out).
class OverlapSweep {
  public:
    /// Robot `robot` with `n_own` poses at rank `rank`. `edges`: every edge touching an own or an
    /// overlap pose (more are ignored); `overlap`: other robots' poses optimised with the own
    /// block (OverlapDomain).
    OverlapSweep(int robot, int n_own, int rank, const std::vector<slam::LoopClosure>& edges,
                 const std::set<slam::PoseId>& overlap, const slam::RbcdConfig& config);
    ~OverlapSweep();
    OverlapSweep(OverlapSweep&&) noexcept;
    OverlapSweep& operator=(OverlapSweep&&) noexcept;

    /// One update of the domain from own block `X_own` and the other robots' poses `others`
    /// (every overlap pose and every pose beyond the domain that an edge touches must be among
    /// them, and X_own of the robot's n_own poses; std::invalid_argument otherwise), until the
    /// domain's gradient is <= grad_tol or dropped by the block reduction. Returns the new own
    /// block; Proposals() holds the overlap.
    Eigen::MatrixXd Sweep(const Eigen::MatrixXd& X_own, const PoseBlocks& others, double grad_tol);
    /// The overlap poses after the last Sweep (empty before): what the neighbours start from.
    const PoseBlocks& Proposals() const;
    /// The domain's gradient norm after the last Sweep.
    double GradNorm() const;
    /// Other robots' poses in the domain.
    int OverlapSize() const;

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

/// The overlap of robot `robot`: poses of robots in `later` (its neighbours that sweep after it)
/// within `depth` edges of its own poses, walking through those robots' poses only. A pose joins
/// only when every pose next to it is `robot`'s or a `later` robot's: the poses fixed beyond the
/// domain are then among those its neighbours send. Two earlier robots may propose the same pose
/// (TeamRounds takes the later sweeper's). `edges`: every edge within depth + 1 of the own poses
/// (more is fine). depth 0: empty.
std::set<slam::PoseId> OverlapDomain(int robot, const std::vector<slam::LoopClosure>& edges,
                                     int depth, const std::set<int>& later);

/// Every edge touching `me`'s poses, each once (odometry and loops).
std::vector<slam::LoopClosure> EdgesTouching(const SolverState& me);

/// Robot `me`'s poses near its neighbours in rounds of overlap `depth`, from its graph alone
/// (fixed while the graph is: the caller keeps it until the graph changes). An "end" is an own
/// pose with an edge to another robot; a neighbour's domain enters the own block only there.
struct RoundBoundary {
    int depth = 0;  ///< the overlap depth it was computed for
    /// The own poses sent each round, ascending: within `depth` own edges of an end (what the
    /// neighbours' domains read, held fixed or optimised) and pose 0. Empty at depth 0.
    std::vector<slam::PoseId> sent;
    /// Own pose indices within depth - 1 own edges of an end: every own pose a neighbour's
    /// domain can hold (a path of at most `depth` edges enters through an end), so every one an
    /// earlier neighbour may propose (TeamRounds::SetProposable). Empty at depth 0.
    std::set<int> proposable;
    /// Sent with the round-0 poses: the edges touching a proposable pose (its domain's edges).
    std::vector<slam::LoopClosure> edges;
};

/// The boundary of `me`'s current graph for overlap `depth` (>= 0).
RoundBoundary BoundaryOf(const SolverState& me, int depth);

/// What robot `me` sends after its placement or sweep of `round`, `boundary` being its
/// BoundaryOf: depth 0, its public poses; otherwise the boundary's sent poses, its edges at
/// round 0 and the proposals of `sweep` after an overlapping sweep.
PoseBlocks RoundPoses(const SolverState& me, const RoundBoundary& boundary, std::uint64_t round,
                      std::uint64_t iteration, const OverlapSweep* sweep);

/// Robot `me`'s sweep of round action `a` (kSweep): an overlapping one of `depth` whose domain
/// (built at the first sweep into `*sweep`, from its own edges and those its neighbours sent) is
/// not empty, otherwise RBCD's block update (also from the first domain pose no neighbour sent
/// on). With `a.overlap` false, RBCD's block update, and `*sweep` is freed (no more proposals).
/// Returns the block gradient norm after it.
double SweepRound(const RoundAction& a, int depth, const slam::RbcdConfig& rbcd,
                  const TeamRounds& rounds, SolverState* me, std::optional<OverlapSweep>* sweep);

}  // namespace certislam::certify
