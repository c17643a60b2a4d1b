// Exact maximum clique of an undirected graph, the combinatorial core of PCM (pcm.h).
#pragma once

#include <cstdint>
#include <vector>

namespace certislam::slam {

/// Exact maximum clique of an undirected graph given as adjacency lists (branch and bound with
/// a greedy-colouring bound, Tomita & Seki's MCQ). `*nodes` counts branch nodes; the search
/// stops after `max_nodes` and returns the best clique so far (then *exact = false).
std::vector<int> MaximumClique(const std::vector<std::vector<int>>& adjacency,
                               std::int64_t max_nodes, std::int64_t* nodes, bool* exact);

}  // namespace certislam::slam
