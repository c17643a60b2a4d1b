// A team's synchronous RBCD++ rounds with every message delivered at once: what the solver
// actors of `solve --distributed` compute, without sockets (tests, benchmarks).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "certify/pipeline/solver_state.h"
#include "certify/pipeline/team_finish.h"
#include "certify/pipeline/team_rounds.h"
#include "slam/core/graph_split.h"

namespace certislam::certify {

/// Result of RunTeamRoundsInMemory.
struct InMemoryTeam {
    std::vector<SolverState> robots;    ///< one per graph, in the graphs' order, at the last round
    std::vector<bool> converged;        ///< per robot: reached kConverged (false: gave up)
    std::vector<std::uint64_t> rounds;  ///< per robot: rounds swept
    std::vector<int> restarts;          ///< per robot: adaptive restarts
    std::vector<std::uint64_t> rejected_proposals;  ///< per robot: TeamRounds::RejectedProposals

    /// True when every robot converged.
    bool AllConverged() const;
    /// The team's X: every robot's block in the robots' order (r x (d+1)n).
    Eigen::MatrixXd X() const;
    /// The team's f, each robot's share as its SolverState evaluates it (its block against the
    /// neighbours' poses it holds).
    double Cost();
    /// The team's Riemannian gradient norm from the robots' block gradients (the same way).
    double GradientNorm();
};

/// Runs the robots of a split graph (slam::SplitGraph; every edge arrives as a loop, as a pose
/// graph's robot receives it) through TeamRounds until every robot converged or gave up.
InMemoryTeam RunTeamRoundsInMemory(const std::vector<slam::RobotGraph>& graphs, SolverConfig solver,
                                   const TeamRoundsConfig& rounds);

/// Result of RunTeamFinishInMemory.
struct InMemoryFinish {
    std::vector<TeamFinish::Status> status;    ///< per robot
    std::vector<TeamFinishProgress> progress;  ///< per robot (the same but entries_sent)
    double entries = 0.0;                      ///< doubles of vectors all robots sent
    double scalars = 0.0;                      ///< doubles of sums all robots sent
    std::size_t edges = 0;                     ///< edges sent for the Schwarz domains

    /// True when every robot converged.
    bool AllConverged() const;
};

/// Runs every robot of `team` (at their current blocks) through TeamFinish, every message handed
/// over at once, and leaves the finished blocks in `team->robots`.
InMemoryFinish RunTeamFinishInMemory(InMemoryTeam* team, const TeamFinishConfig& config);

}  // namespace certislam::certify
