// One robot's share of synchronous RBCD++ over messages (Tian et al., T-RO 2021, Alg. 3 with
// adaptive restart), without sockets: robots sweep in colour order (Gauss-Seidel: a robot starts
// from this round's poses of neighbours of a lower colour and the extrapolated poses of the others;
// neighbours never share a colour, so each colour's robots sweep at once), then every
// robot sends its share of f and its block gradient norm (a scalar all-reduce), from which every
// robot takes the same accept / restart / stop decision. Needs only neighbour exchanges and sums.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "certify/pipeline/solver_state.h"

namespace certislam::certify {

/// Settings of the synchronous rounds.
struct TeamRoundsConfig {
    bool acceleration = true;  ///< Nesterov extrapolation with adaptive restart (RBCD++)
    /// Stop: ||rgrad f|| (from the robots' block gradients) <= this * max(1, f), > 0. Tighter
    /// than RbcdConfig::rel_grad_tol: the certificate's bound needs lambda_min(S) near 0, and
    /// S's error is first order in the gradient.
    double rel_grad_tol = 1e-8;
    /// Below rel_grad_tol the rounds go on towards this tolerance, (0, rel_grad_tol]: at an
    /// inexact X the smallest eigenvalue of S dips below 0 along the translations, and the
    /// certificate's bound grows with |lambda_min| tr(X^T X), so a metric-scale map (sphere2500)
    /// needs a gradient well below rel_grad_tol to be certified within 1e-6, and its
    /// eigen-solve converges in far fewer steps there.
    double refine_rel_grad_tol = 1e-10;
    /// Rounds of refinement at most, >= 0 (RBCD++'s tail is linear: a graph that gains a decade
    /// in a few rounds reaches refine_rel_grad_tol, a slow one stops near rel_grad_tol); 0: none.
    int refine_rounds = 40;
    double local_tol_factor = 0.1;  ///< a block update stops at this * the team tolerance, (0, 1]
    int max_rounds = 1000;  ///< rounds before giving up (the caller goes asynchronous), >= 1
    /// From this round on, rounds whose linear rate (the team gradient's low over the last
    /// kRateWindow rounds) projects rel_grad_tol beyond kHopeless max_rounds end early (kGaveUp,
    /// HandedOver()): the caller hands the team to a faster method. 0: never. >= 0.
    int hand_over_after = 0;
    /// Overlapping sweeps (OverlapSweep): a robot's block update also moves the poses of
    /// later-sweeping neighbours within this many edges of its own, and they go on from there.
    /// 0: each robot its own poses (RBCD). In [0, 16].
    int overlap_depth = 4;
};

/// What the robot should do next.
struct RoundAction {
    enum class Kind {
        kWait,       ///< a neighbour's poses or a robot's sums of the last round are missing
        kAlign,      ///< round 0: place the own block through a loop to a lower neighbour's
                     ///< poses in `neighbours` (their round 0), then SweepDone(0, block)
        kSweep,      ///< update the own block from `own_start` against `neighbours`
        kEvaluate,   ///< every neighbour's poses of `round` are in: own share of f and gradient
        kConverged,  ///< the team's gradient is below tolerance at round `round` (accepted)
        kGaveUp,     ///< max_rounds reached
    };
    Kind kind = Kind::kWait;
    std::uint64_t round = 0;    ///< the round this action belongs to
    Eigen::MatrixXd own_start;  ///< kSweep: own block to start from; kConverged: the solution
    PoseBlocks neighbours;      ///< kSweep, kEvaluate, kConverged: neighbours' poses to use
    double block_tol = 0.0;     ///< kSweep: the block update's gradient tolerance (absolute)
    /// kSweep: the sweep may be an overlapping one (OverlapSweep); false, own poses only: every
    /// robot's, once a round without extrapolation raised f (Overlapping()).
    bool overlap = false;
};

/// A message a robot's rounds wait for: robot `robot`'s poses (or sums) of round `round`.
struct RoundWant {
    int robot = 0;
    std::uint64_t round = 0;
    bool sums = false;  ///< its share of f and gradient norm; false: its poses
    bool operator==(const RoundWant& o) const {
        return robot == o.robot && round == o.round && sums == o.sums;
    }
};

/// One robot's synchronous RBCD++ bookkeeping (plain data in and out).
class TeamRounds {
  public:
    /// Robot `robot` of `robots` (every robot's sums are awaited), sharing edges with
    /// `neighbours`. Round 0 places the robots in id order (kAlign); sweeps start at round 1.
    TeamRounds(int robot, std::vector<int> robots, std::set<int> neighbours,
               TeamRoundsConfig config);

    /// A neighbour's public poses after its sweep of `round` (round 0: its starting block).
    void OnPoses(int robot, std::uint64_t round, const PoseBlocks& poses);
    /// A robot's share of f and its block gradient norm at `round`'s candidate.
    void OnSums(int robot, std::uint64_t round, double cost, double grad_norm);
    /// The next action (the caller does it, then reports with SweepDone or OnSums for itself).
    RoundAction Next();
    /// The own block after the sweep (or placement) of `round`.
    void SweepDone(std::uint64_t round, const Eigen::MatrixXd& own_candidate);

    /// The robots this one shares edges with: the only ones whose poses it takes.
    const std::set<int>& Neighbours() const { return neighbours_; }
    /// Rounds swept so far (round 0 is the start, not a sweep).
    std::uint64_t Rounds() const { return swept_; }
    /// Adaptive restarts so far: rounds dropped because f rose, and kept extrapolated rounds
    /// whose gradient norm rose while f changed by at most 1e-9 f (the next sweeps without
    /// extrapolation).
    int Restarts() const { return restarts_; }
    /// True while the sweeps may overlap (config overlap_depth > 0). An overlapping sweep need
    /// not lower f (OverlapSweep), own-pose sweeps do (RBCD): a round without extrapolation whose
    /// f rose is dropped (counted in Restarts), and from the next one every robot sweeps its own
    /// poses for the rest of these rounds (the same decision on every robot, from the same sums,
    /// when the team shares one overlap_depth), so the rounds keep RBCD's descent.
    /// OverlapEndedAt() says at which round.
    bool Overlapping() const { return overlapping_; }
    /// The round whose rise ended the overlap (none while Overlapping()).
    std::optional<std::uint64_t> OverlapEndedAt() const { return overlap_ended_; }
    /// This robot's colour in the sweeps' order, set when it is placed (round 0): the smallest
    /// not taken by a lower neighbour (greedy colouring in id order). Robots of one colour share
    /// no edge and sweep together; a colour sweeps after every lower one. The round-0 poses
    /// carry it (PoseBlocks::sweep_color) to the neighbours.
    int SweepColor() const { return color_; }
    /// Neighbours that sweep after this robot in every round from 1 on (known once placed): the
    /// robots whose poses an overlapping sweep may propose (OverlapSweep).
    std::set<int> LaterNeighbours() const;
    /// The own pose indices an earlier neighbour's overlapping sweep may propose (its domain's
    /// reach into this robot: RoundBoundary::proposable). A proposal of another own pose, of one
    /// outside the block, of another rank, or whose block is not a finite pose of the lifted
    /// manifold is dropped and counted (RejectedProposals) when the sweep it was for starts.
    /// Until set, none is taken.
    void SetProposable(std::set<int> indices) { proposable_ = std::move(indices); }
    /// Proposals dropped so far (SetProposable).
    std::uint64_t RejectedProposals() const { return rejected_; }
    /// The edges the neighbours sent with their round-0 poses (PoseBlocks::edges; the first
    /// heard from each stays): what an overlapping sweep's domain needs beyond the own edges.
    std::vector<slam::LoopClosure> NeighbourEdges() const;
    /// The rounds ended early: their rate projected rel_grad_tol beyond max_rounds
    /// (TeamRoundsConfig::hand_over_after).
    bool HandedOver() const { return handed_over_; }
    /// The messages Next() waits for, in robot order: a stalled robot asks their senders for
    /// them (the senders keep their last two rounds' messages); empty when it does not wait for
    /// a message (converged, given up, or an action is due). A sweep waits for its earlier
    /// neighbours' poses of the round and its later ones' of the accepted rounds it extrapolates.
    std::vector<RoundWant> Wants() const;
    /// Wants() for a log line ("round 3: the sums of robots 7, 9").
    std::string Waiting() const;
    /// Robots Waiting() lists by id at most (the rest counted).
    static constexpr std::size_t kWaitingListed = 8;
    /// Rounds over which hand_over_after measures the rate.
    static constexpr std::uint64_t kRateWindow = 20;
    /// ... and how far beyond max_rounds that rate must project rel_grad_tol.
    static constexpr double kHopeless = 4.0;

  private:
    /// hand_over_after's test at the accepted round current_ with gradient `grad`.
    bool RateTooSlow(double grad, double scale) const;
    /// True when neighbour j sweeps `round` before this robot: round 0 in id order, later rounds
    /// in colour order.
    bool Earlier(int j, std::uint64_t round) const;
    /// Neighbour j's poses that the sweep (`lower_only`) or the evaluation of `round` needs are
    /// in.
    bool HaveNeighbour(int j, std::uint64_t round, bool lower_only) const;
    /// The round of neighbour j's poses that HaveNeighbour misses (none when it has them).
    std::optional<std::uint64_t> MissingRound(int j, std::uint64_t round, bool lower_only) const;
    bool HaveNeighbours(std::uint64_t round, bool lower_only) const;
    /// Own poses that an earlier neighbour's overlapping sweep of `round` proposed replace those
    /// of the start (multiplicative Schwarz: the sweep goes on from them); of two proposals of
    /// one pose, the later sweeper's. Only poses in proposable_, while Overlapping() (the others
    /// are counted).
    void ApplyProposals(std::uint64_t round, Eigen::MatrixXd* own_start);
    PoseBlocks NeighbourPoses(std::uint64_t round, bool extrapolate_higher) const;
    void Decide();
    void Prune();
    /// The team's gradient tolerance the sweeps work towards (relative to max(1, f)).
    double TeamTolerance() const;

    int robot_;
    std::vector<int> robots_;
    std::set<int> neighbours_;
    TeamRoundsConfig config_;
    std::map<std::uint64_t, Eigen::MatrixXd> own_;  ///< own block by round
    std::map<int, std::map<std::uint64_t, PoseBlocks>> nbr_;
    std::map<int, int> colors_;  ///< neighbours' sweep colours, from their round-0 poses
    std::map<int, std::vector<slam::LoopClosure>> edges_;  ///< neighbours' round-0 edges
    std::set<int> proposable_;              ///< own poses a neighbour may propose (SetProposable)
    std::uint64_t rejected_ = 0;            ///< proposals dropped
    std::optional<std::uint64_t> counted_;  ///< the round whose proposals rejected_ counted
    int color_ = 0;                         ///< own sweep colour (set with the round-0 placement)
    std::map<std::uint64_t, std::map<int, std::pair<double, double>>> sums_;
    std::uint64_t current_ = 0;        ///< the round in progress (0: start)
    bool evaluated_ = false;           ///< own sums of current_ sent
    std::uint64_t accepted_ = 0;       ///< last accepted round
    std::uint64_t accepted_prev_ = 0;  ///< the accepted round before it
    bool plain_ = false;               ///< current_ restarts from accepted_ without extrapolation
    double gamma_ = 1.0;               ///< Nesterov weight of accepted_
    double beta_ = 0.0;                ///< extrapolation weight of current_
    double gamma_next_ = 1.0;          ///< gamma if current_ is accepted
    double accepted_cost_ = 0.0;       ///< f at accepted_
    double accepted_grad_ = 0.0;       ///< ||rgrad f|| at accepted_ (gradient restart)
    bool overlapping_;                 ///< Overlapping() (from the config's overlap_depth)
    std::optional<std::uint64_t> overlap_ended_;  ///< OverlapEndedAt()
    std::optional<std::uint64_t> within_;         ///< first round accepted below rel_grad_tol
    bool converged_ = false;
    bool handed_over_ = false;
    std::vector<double> best_grads_;  ///< the smallest accepted team gradient, after each round
    std::uint64_t swept_ = 0;
    int restarts_ = 0;
};

}  // namespace certislam::certify
