// Splitting a pose graph's poses into robots (blocks of contiguous global indices).
#pragma once

#include <vector>

#include "slam/core/pose_graph.h"

namespace certislam::slam {

/// Poses split into robots; robot k owns the contiguous global range [begin[k], begin[k+1]).
struct Partition {
    std::vector<int> begin;  ///< size num_robots() + 1; begin[0] = 0, back() = n

    /// Number of robots.
    int num_robots() const { return static_cast<int>(begin.size()) - 1; }
    /// Number of poses of robot k.
    int size(int k) const { return begin[k + 1] - begin[k]; }
    /// Robot owning global pose g (binary search).
    int RobotOf(int g) const;
};

/// dpgo's convention: robots of floor(n / num_robots) poses, the last one takes the remainder.
/// Throws std::invalid_argument unless 1 <= num_robots <= n.
Partition ContiguousPartition(int n, int num_robots);

/// The partition given by `graph.ids` (robots must be contiguous and ascending, as the readers
/// build them). Throws std::invalid_argument otherwise.
Partition PartitionFromIds(const PoseGraph& graph);

/// Greedy colouring of the robot graph (robots adjacent when an edge joins them): robots of one
/// colour share no edge and can be updated in parallel. Returns colour classes, each a robot list.
std::vector<std::vector<int>> ColourRobots(const PoseGraph& graph, const Partition& partition);

/// Number of public poses: those an inter-robot edge touches (the poses a robot shares with its
/// neighbours in every RBCD iteration).
int CountPublicPoses(const PoseGraph& graph);

}  // namespace certislam::slam
