// `certislam solve FILE --distributed`: the file's graph split into robots, each robot its own
// source, solver and certifier actors over real sockets (inproc, one process), and the JSON or
// text report of that run.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "actors/pose_graph_team.h"
#include "bin/team_result.h"
#include "slam/core/pose_graph.h"

namespace certislam::bin {

/// How the distributed solve runs.
struct DistributedSolveOptions {
    std::string file;        ///< the input (for messages and the report)
    int robots = -1;         ///< contiguous robots; -1: the graph's own robots (`graph.ids`)
    double timeout_s = 600;  ///< give up (not certified) after this long
    bool json = false;       ///< one JSON object on stdout
    double max_relative_bound = 1e-6;    ///< certified needs a relative bound at most this
    double quiet_s = 0.3;                ///< done: certified and unchanged this long
    std::string transport = "inproc";    ///< inproc (one process), ipc or tcp (robot processes)
    std::string eigensolver = "lobpcg";  ///< the certificate's: lobpcg or lanczos
    /// The rounds' overlapping sweeps (solver.rounds_overlap); -1: the configuration's default.
    int overlap = -1;
    /// Rounds before the team's finish (solver.finish_after_rounds); -1: the default.
    int finish_after = -1;
    int max_rounds = -1;  ///< rounds at most (solver.rounds_max); -1: the default
};

/// Adds the file's fields to the team's report `j` (of `result`) and prints it (JSON or text);
/// returns the command's exit code (certified or not). A planar graph's lift certifies the
/// planar graph only when its optimum stays in the plane (else "inconclusive").
int PrintDistributedReport(nlohmann::json* j, const actors::PoseGraphTeamResult& result,
                           const slam::PoseGraph& graph, const DistributedSolveOptions& options);

/// Runs the team on `graph` over `options.transport`; prints the report; returns the command's
/// exit code.
int RunDistributedSolve(const slam::PoseGraph& graph, const DistributedSolveOptions& options);

}  // namespace certislam::bin
