// A pose graph split into robots by a partition, as each robot's back end receives it: its own
// poses' initial guesses, its intra-robot edges and the inter-robot edges it shares (dpgo's
// multi-robot split of a single-robot benchmark).
#pragma once

#include <Eigen/Geometry>
#include <vector>

#include "slam/core/loop_closure.h"
#include "slam/core/partition.h"
#include "slam/core/pose_graph.h"

namespace certislam::slam {

/// One robot's share of a split graph, in robot-local pose ids (PoseId{robot, index}).
struct RobotGraph {
    int robot = 0;                           ///< this robot
    std::vector<Eigen::Isometry3d> initial;  ///< initial guess of each own pose (common frame)
    std::vector<LoopClosure> intra;          ///< edges with both ends own, file order
    std::vector<LoopClosure> inter;          ///< edges with the tail own and the head not
    std::vector<LoopClosure> shared;         ///< edges with the head own and the tail not
    /// f_file(X) - f_merged(X) of the merged edges whose tail is own (MergeParallelEdges), >= 0
    double cost_offset = 0.0;
};

/// A graph with its parallel edges merged: one edge per ordered pair (tail, head).
struct MergedGraph {
    PoseGraph graph;           ///< first edge of each pair in file order, carrying the merge
    std::vector<double> cost;  ///< per merged edge: f_file - f_merged of its group (0 if alone)
    int merged = 0;            ///< edges folded into an earlier one
};

/// Merges the edges k with the same tail i and head j into one, exactly (MATH.md objective):
/// sum_k tau_k |t_j - t_i - R_i t_k|^2 = tau |t_j - t_i - R_i t_bar|^2 + sum_k tau_k |t_k -
/// t_bar|^2 with tau = sum tau_k, t_bar = sum tau_k t_k / tau; kappa = sum kappa_k and R_bar = sum
/// kappa_k R_k / kappa (not a rotation when the R_k differ) keep the rotation terms exactly, as Q
/// counts ||R_i R~||^2 as d (slam::ConnectionLaplacian). So for every X on the Stiefel manifold the
/// merged cost is the file's minus the constant `cost`, and Q differs only by the symmetric tau t
/// t^T terms of the tail's rotation block, which Lambda absorbs: S = Q - Lambda, its eigenvalues
/// and the bound's gap are the file's. Edges i -> j and j -> i stay two edges (a translation
/// residual is measured in its tail's frame).
MergedGraph MergeParallelEdges(const PoseGraph& graph);

/// Sum of the robots' cost_offset: add it to a split team's cost to get the file's.
double CostOffset(const std::vector<RobotGraph>& graphs);

/// A planar graph embedded in SE(3): rotations about z, z = 0, the same weights. A planar X has
/// the same cost in both, so the lifted optimum is a lower bound on the planar one, and equal to
/// it when the lifted optimum is planar. A 3D graph is returned as it is.
PoseGraph LiftPlanar(const PoseGraph& graph);

/// Splits a graph (a planar one as LiftPlanar embeds it): robot k owns global poses
/// [partition.begin[k], partition.begin[k + 1]). Initial guesses are the graph's VERTEX estimates
/// when it has them, else the chain of edges g -> g + 1 composed from pose 0 (identity where a step
/// has no such edge). Parallel edges are merged (MergeParallelEdges: a robot's solver keeps one
/// edge per ordered pose pair), every other edge keeps its measurement and weights. Throws
/// std::invalid_argument when the partition does not cover [0, n).
std::vector<RobotGraph> SplitGraph(const PoseGraph& graph, const Partition& partition);

}  // namespace certislam::slam
