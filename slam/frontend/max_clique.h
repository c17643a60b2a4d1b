// Exact maximum clique of an undirected graph, the combinatorial core of PCM (pcm.h).
#pragma once

#include <cstdint>
#include <vector>

namespace certislam::slam {

/// Exact maximum clique of an undirected graph given as adjacency lists (branch and bound with
/// a greedy-colouring bound, Tomita & Seki's MCQ). `*nodes` counts the work: every branch node
/// costs one plus its candidates (its colouring is what takes the time); the search stops after
/// `max_nodes` and returns the best clique so far (then *exact = false). `seed`, when it is a
/// clique of the graph, is where the search starts from (the last answer of a graph that only
/// gained vertices): only larger cliques are searched for, and it is the answer if none is found.
std::vector<int> MaximumClique(const std::vector<std::vector<int>>& adjacency,
                               std::int64_t max_nodes, std::int64_t* nodes, bool* exact,
                               const std::vector<int>& seed = {});

}  // namespace certislam::slam
