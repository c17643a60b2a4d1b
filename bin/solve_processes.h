// `certislam solve FILE --distributed --transport ipc|tcp`: each robot a `certislam-robot`
// process of its own on this host (a generated team configuration with a pose-graph source),
// over Unix sockets or tcp; their reports merged into the one report of the team.
#pragma once

#include <nlohmann/json.hpp>
#include <vector>

#include "actors/pose_graph_team.h"
#include "bin/solve_distributed.h"
#include "slam/core/partition.h"
#include "slam/core/pose_graph.h"

namespace certislam::bin {

/// The team's result from its robots' own reports (`certislam robot --json` on a pose-graph
/// source, the anchor first): bytes and iterations per robot, the anchor's certificate. Throws
/// std::runtime_error naming the robot and field when a report lacks one.
actors::PoseGraphTeamResult MergeRobotReports(const std::vector<nlohmann::json>& reports);

/// Runs the team of `partition` as separate robot processes; prints the merged report (peak RSS
/// per process measured by this parent); returns the command's exit code.
int RunProcessSolve(const slam::PoseGraph& graph, const slam::Partition& partition,
                    const DistributedSolveOptions& options);

}  // namespace certislam::bin
