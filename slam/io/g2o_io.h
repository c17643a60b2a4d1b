// Reading and writing pose graphs in the g2o text format (EDGE_SE2, EDGE_SE3:QUAT, VERTEX_*).
#pragma once

#include <istream>
#include <string>

#include "slam/core/pose_graph.h"

namespace certislam::slam {

/// Outcome of reading a pose-graph file. On failure `error` names file:line and the reason.
struct PoseGraphReadResult {
    enum class Status {
        kOk,            ///< `graph` holds the file's graph
        kFileError,     ///< the file could not be opened
        kParseError,    ///< a line was malformed (unknown token, too few numbers, non-finite, ...)
        kDisconnected,  ///< the parsed graph is not connected (or has no edges)
    };
    Status status = Status::kOk;
    PoseGraph graph;    ///< the graph (valid only when status == kOk)
    std::string error;  ///< "file:line: reason" (empty when status == kOk)

    /// True when the read succeeded.
    bool ok() const { return status == Status::kOk; }
};

/// Reads a g2o file. kappa and tau follow SE-Sync's rules (data/g2o/README.md); quaternions are
/// not renormalised; blank lines and `#` comments are skipped; duplicate edges, multi-edges and
/// edges with i > j are kept as written; `FIX` lines are accepted and ignored; n = max id + 1.
/// VERTEX lines fill `initial_guess` when every pose has one. All poses get robot 0.
PoseGraphReadResult ReadG2o(const std::string& path);

/// Same as ReadG2o for text already open; `name` is used in error messages.
PoseGraphReadResult ReadG2oStream(std::istream& in, const std::string& name);

/// Writes `poses` (d x (d+1)n, blocks [R_g t_g]) as VERTEX lines followed by the graph's edges.
/// Edges are written with the isotropic information matrix that reproduces their kappa and tau
/// under ReadG2o's rules (the file's off-diagonal information terms are not kept). Returns false
/// and sets *error when the file cannot be written.
bool WriteG2o(const std::string& path, const PoseGraph& graph, const PoseMatrix& poses,
              std::string* error);

/// True when every pose is reached from pose 0 through the edges (and the graph has n >= 1).
bool IsConnected(const PoseGraph& graph);

}  // namespace certislam::slam
