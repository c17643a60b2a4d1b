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
};

/// A planar graph embedded in SE(3): rotations about z, z = 0, the same weights. A planar X has
/// the same cost in both, so the lifted optimum is a lower bound on the planar one, and equal to
/// it when the lifted optimum is planar. A 3D graph is returned as it is.
PoseGraph LiftPlanar(const PoseGraph& graph);

/// Splits a graph (a planar one as LiftPlanar embeds it): robot k owns global poses
/// [partition.begin[k], partition.begin[k + 1]). Initial guesses are the graph's VERTEX estimates
/// when it has them, else the chain of edges g -> g + 1 composed from pose 0 (identity where a step
/// has no such edge). Every edge keeps its measurement and weights. Throws std::invalid_argument
/// when the partition does not cover [0, n), or two edges join the same pair of poses (a robot's
/// solver keeps one edge per pose pair); the message names the edges.
std::vector<RobotGraph> SplitGraph(const PoseGraph& graph, const Partition& partition);

}  // namespace certislam::slam
