// `certislam solve FILE --distributed`: the file's graph split into robots, each robot its own
// source, solver and certifier actors over real sockets (inproc, one process), and the JSON or
// text report of that run.
#pragma once

#include <string>

#include "slam/core/pose_graph.h"

namespace certislam::bin {

/// How the distributed solve runs.
struct DistributedSolveOptions {
    std::string file;        ///< the input (for messages and the report)
    int robots = -1;         ///< contiguous robots; -1: the graph's own robots (`graph.ids`)
    double timeout_s = 600;  ///< give up (not certified) after this long
    bool json = false;       ///< one JSON object on stdout
};

/// Runs the team on `graph`; prints the report; returns the command's exit code.
int RunDistributedSolve(const slam::PoseGraph& graph, const DistributedSolveOptions& options);

}  // namespace certislam::bin
