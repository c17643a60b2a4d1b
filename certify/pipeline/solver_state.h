// One robot's asynchronous RBCD state, without sockets: its odometry chain and loop closures,
// the last known poses of its neighbours, its lifted block, warm starts on every new edge, and
// its trajectory anchored in the team frame (plain data in and out). The solver actor is this
// plus messaging.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <vector>

#include "certify/pipeline/edge_noise.h"
#include "slam/backend/rbcd.h"
#include "slam/core/loop_closure.h"
#include "slam/core/pose_graph.h"

namespace certislam::certify {

/// Lifted poses of some pose ids: what RBCD solvers exchange.
struct PoseBlocks {
    std::vector<slam::PoseId> ids;  ///< one per block
    Eigen::MatrixXd blocks;         ///< r x (d+1)|ids|, block k = [Y_k p_k]
    std::uint64_t iteration = 0;    ///< sender's RBCD iteration
    int staircase_level = 0;        ///< sender's saddle escapes so far
    std::uint64_t team_round = 0;   ///< 1 + synchronous round (TeamRounds); 0: asynchronous
    int sweep_color = 0;            ///< synchronous rounds: the sender's TeamRounds::SweepColor
    /// Round 0 of overlapping sweeps: the sender's edges near its neighbours (RoundPoses).
    std::vector<slam::LoopClosure> edges{};
};

/// Settings of one robot's solver.
struct SolverConfig {
    int rank = 5;           ///< relaxation rank r, >= 3
    EdgeNoiseConfig noise;  ///< odometry edge weights (loops carry their own)
    /// Block trust-region settings (rel_grad_tol used); truncated CG stops at half the block's
    /// gradient tolerance at the latest, as certify::StaircaseConfig's: a block update stops at
    /// that tolerance anyway, so a tighter inner solve buys nothing.
    slam::RbcdConfig rbcd = [] {
        slam::RbcdConfig c;
        c.tcg_residual_floor = 0.5;
        return c;
    }();
    /// True: consecutive keyframes are joined by an odometry edge weighted by `noise` (a LiDAR
    /// front end). False: keyframe poses are initial guesses only and every edge, odometry
    /// included, arrives as a loop closure with its own weights (a pose-graph file's robot).
    bool odometry_edges = true;

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// What one Step did.
struct SolverStepResult {
    enum class Status {
        kIdle,      ///< no poses yet
        kImproved,  ///< the block moved
        kLocalOk,   ///< block gradient below tolerance given the neighbours' last poses
        kStuck,     ///< no step accepted above tolerance
    };
    Status status = Status::kIdle;
    double grad_norm = 0.0;  ///< block Riemannian gradient norm after the step
    double cost = 0.0;       ///< this robot's share of f (edges whose tail is its own pose)
    bool rebuilt = false;    ///< the graph changed and the agent was rebuilt (warm start)
    bool moved = false;      ///< the block moved (also when it ends below tolerance: kLocalOk)
};

/// One robot's share of the team's pose graph and of RBCD.
class SolverState {
  public:
    /// Robot `robot` with `config` (validated).
    SolverState(int robot, SolverConfig config);
    ~SolverState();
    SolverState(SolverState&&) noexcept;
    SolverState& operator=(SolverState&&) noexcept;

    /// Adds own keyframe `index` at odometry pose T_odom; indices must arrive in order (a gap or a
    /// repeat returns false and changes nothing). The new pose is predicted by odometry.
    bool AddKeyframe(int index, const Eigen::Isometry3d& T_odom);
    /// Adds a loop closure touching this robot (false when it does not, or is already known).
    /// Inter-robot loops to poses not yet known are kept until both ends exist.
    bool AddLoop(const slam::LoopClosure& loop);
    /// Removes the loop with ends (a, b), the matcher having withdrawn it (false when unknown);
    /// the graph is rebuilt at the next Step.
    bool RemoveLoop(const slam::PoseId& a, const slam::PoseId& b);
    /// Stores a neighbour's latest public poses (ids of other robots only; newer replace older).
    void SetNeighbourPoses(const PoseBlocks& poses);
    /// Replaces the own block with a lifted solution of rank >= r (the saddle escape's output):
    /// blocks in own index order. Ignored unless its size matches the own poses.
    bool AdoptBlock(const Eigen::MatrixXd& X_own, int staircase_level);

    /// Rebuilds the agent if the graph changed, then a few trust-region steps on the block
    /// against the neighbours' last known poses (RBCD Alg. 1 line 4, asynchronous).
    /// `team_cost` scales the tolerance (tolerance_scale * rel_grad_tol * max(1, team_cost)).
    SolverStepResult Step(double team_cost, double tolerance_scale = 1.0);
    /// Same with the block's gradient tolerance given (absolute).
    SolverStepResult StepTo(double grad_tol);
    /// This robot's share of f and its block gradient norm against the neighbours' last poses
    /// (no step taken).
    SolverStepResult Evaluate();
    /// Replaces the own block (same size; the synchronous rounds' extrapolated start).
    void SetOwnBlock(const Eigen::MatrixXd& X_own);
    /// Own poses from the chordal relaxation of the own edges alone (no neighbour needed), moved
    /// rigidly so own pose 0 stays where it was. False (nothing changed) when the own edges do
    /// not join every own pose.
    bool LocalChordalStart();
    /// Moves the block rigidly through a loop into the frame of the lowest neighbour whose poses
    /// are known (DiSCo-style placement at first encounter); false when none is known.
    bool AlignToLowerNeighbour();

    /// Own public poses (ends of inter-robot edges) and always own pose 0 (the anchor).
    PoseBlocks PublicPoses(std::uint64_t iteration) const;
    /// The whole own block (r x 4n) with own ids.
    PoseBlocks FullBlock(std::uint64_t iteration) const;
    /// Every neighbour block held, at the current rank, in id order: all that Step and
    /// Trajectory read of the other robots.
    PoseBlocks NeighbourBlocks() const;
    /// Own poses rounded and expressed in the frame of `anchor`'s pose 0 when its lifted pose is
    /// known (own pose 0 otherwise); `*anchor_used` tells which robot anchored them. Caches its
    /// last answer (one caller thread, as everything here).
    std::vector<Eigen::Isometry3d> Trajectory(int anchor, int* anchor_used) const;
    /// Robots this one shares an edge with.
    std::set<int> Neighbours() const;
    /// Inter-robot loops known (own and pending), in arrival order.
    std::vector<slam::LoopClosure> InterRobotLoops() const;
    /// Every own edge as a loop-closure-shaped constraint (odometry and loops whose tail is own):
    /// what a certifier needs to assemble the graph.
    std::vector<slam::LoopClosure> OwnEdges() const;
    /// Number of own keyframes.
    int NumPoses() const;
    /// Current rank of the block.
    int Rank() const;
    /// Saddle escapes adopted so far.
    int StaircaseLevel() const;
    /// This robot.
    int robot() const;

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

/// The team frame of `robot`: the lowest robot id joined to it through inter-robot loops
/// (itself when it has met nobody).
int ComponentAnchor(int robot, const std::vector<slam::LoopClosure>& inter_robot_loops);

/// The lifted pose X_a * T (r x 4): [Y R, Y t + p].
Eigen::MatrixXd LiftedTimes(const Eigen::MatrixXd& X_a, const Eigen::Isometry3d& T);

/// Pose of lifted block X_b in the frame of lifted block X_a: [proj(Y_a^T Y_b), Y_a^T (p_b - p_a)].
Eigen::Isometry3d LiftedRelative(const Eigen::MatrixXd& X_a, const Eigen::MatrixXd& X_b);

}  // namespace certislam::certify
