// Contiguous robot partitions and the colouring of the robot graph.
#include "slam/core/partition.h"

#include <algorithm>
#include <set>
#include <stdexcept>
#include <string>

namespace certislam::slam {

int Partition::RobotOf(int g) const {
    const auto it = std::upper_bound(begin.begin(), begin.end(), g);
    return static_cast<int>(it - begin.begin()) - 1;
}

Partition ContiguousPartition(int n, int num_robots) {
    if (num_robots < 1 || num_robots > n) {
        throw std::invalid_argument("num_robots = " + std::to_string(num_robots) +
                                    ": must be in [1, n = " + std::to_string(n) + "]");
    }
    Partition p;
    const int per_robot = n / num_robots;
    for (int k = 0; k < num_robots; ++k) p.begin.push_back(k * per_robot);
    p.begin.push_back(n);
    return p;
}

Partition PartitionFromIds(const PoseGraph& graph) {
    if (static_cast<int>(graph.ids.size()) != graph.n) {
        throw std::invalid_argument("graph.ids has " + std::to_string(graph.ids.size()) +
                                    " entries: must equal n = " + std::to_string(graph.n));
    }
    Partition p;
    p.begin.push_back(0);
    for (int g = 1; g < graph.n; ++g) {
        const PoseId& prev = graph.ids[g - 1];
        const PoseId& cur = graph.ids[g];
        if (cur.robot == prev.robot) continue;
        if (cur.robot != prev.robot + 1) {
            throw std::invalid_argument(
                "graph.ids: robots must be contiguous and ascending from 0");
        }
        p.begin.push_back(g);
    }
    p.begin.push_back(graph.n);
    return p;
}

std::vector<std::vector<int>> ColourRobots(const PoseGraph& graph, const Partition& partition) {
    const int robots = partition.num_robots();
    std::vector<std::set<int>> adjacent(robots);
    for (const auto& e : graph.edges) {
        const int a = partition.RobotOf(e.i);
        const int b = partition.RobotOf(e.j);
        if (a != b) {
            adjacent[a].insert(b);
            adjacent[b].insert(a);
        }
    }
    // Greedy colouring, robots by decreasing degree (Welsh-Powell).
    std::vector<int> order(robots);
    for (int k = 0; k < robots; ++k) order[k] = k;
    std::stable_sort(order.begin(), order.end(),
                     [&](int a, int b) { return adjacent[a].size() > adjacent[b].size(); });
    std::vector<int> colour(robots, -1);
    int colours = 0;
    for (int k : order) {
        std::set<int> used;
        for (int nb : adjacent[k]) {
            if (colour[nb] >= 0) used.insert(colour[nb]);
        }
        int c = 0;
        while (used.count(c)) ++c;
        colour[k] = c;
        colours = std::max(colours, c + 1);
    }
    std::vector<std::vector<int>> classes(colours);
    for (int k = 0; k < robots; ++k) classes[colour[k]].push_back(k);
    return classes;
}

int CountPublicPoses(const PoseGraph& graph) {
    std::vector<bool> is_public(static_cast<size_t>(graph.n), false);
    for (const auto& e : graph.edges) {
        if (graph.ids[e.i].robot != graph.ids[e.j].robot) is_public[e.i] = is_public[e.j] = true;
    }
    return static_cast<int>(std::count(is_public.begin(), is_public.end(), true));
}

}  // namespace certislam::slam
