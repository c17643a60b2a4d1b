// Exact maximum clique by branch and bound with a greedy-colouring bound (Tomita & Seki 2003,
// MCQ), as PCM needs it; dense bit rows keep the candidate intersections cheap.
#include "slam/frontend/max_clique.h"

#include <algorithm>
#include <cstdint>
#include <vector>

namespace certislam::slam {
namespace {

class CliqueSearch {
  public:
    CliqueSearch(const std::vector<std::vector<int>>& adjacency, std::int64_t max_nodes)
        : n_(static_cast<int>(adjacency.size())),
          adjacent_(static_cast<size_t>(n_) * n_, 0),
          max_nodes_(max_nodes) {
        for (int u = 0; u < n_; ++u) {
            for (const int v : adjacency[u]) {
                if (v != u) adjacent_[Index(u, v)] = adjacent_[Index(v, u)] = 1;
            }
        }
    }

    /// Starts from `clique` when it is one (distinct vertices, pairwise adjacent).
    void Seed(const std::vector<int>& clique) {
        for (size_t i = 0; i < clique.size(); ++i) {
            if (clique[i] < 0 || clique[i] >= n_) return;
            for (size_t j = 0; j < i; ++j) {
                if (clique[i] == clique[j] || !adjacent_[Index(clique[i], clique[j])]) return;
            }
        }
        best_ = clique;
    }

    std::vector<int> Run() {
        // Initial order: by degree, highest last (MCQ expands from the end of the list).
        std::vector<int> order(n_);
        std::vector<int> degree(n_, 0);
        for (int u = 0; u < n_; ++u) {
            order[u] = u;
            for (int v = 0; v < n_; ++v) degree[u] += adjacent_[Index(u, v)];
        }
        std::stable_sort(order.begin(), order.end(),
                         [&](int a, int b) { return degree[a] < degree[b]; });
        Expand(order);
        return best_;
    }

    std::int64_t nodes() const { return nodes_; }
    bool exact() const { return nodes_ <= max_nodes_; }

  private:
    size_t Index(int u, int v) const { return static_cast<size_t>(u) * n_ + v; }

    // Greedy colouring of `candidates` in their order; returns them sorted by colour with
    // the colour numbers (1-based) in `colours`.
    void ColourSort(const std::vector<int>& candidates, std::vector<int>& sorted,
                    std::vector<int>& colours) const {
        std::vector<std::vector<int>> classes;
        for (const int v : candidates) {
            size_t c = 0;
            for (; c < classes.size(); ++c) {
                const bool conflict = std::any_of(classes[c].begin(), classes[c].end(),
                                                  [&](int w) { return adjacent_[Index(v, w)]; });
                if (!conflict) break;
            }
            if (c == classes.size()) classes.emplace_back();
            classes[c].push_back(v);
        }
        sorted.clear();
        colours.clear();
        for (size_t c = 0; c < classes.size(); ++c) {
            for (const int v : classes[c]) {
                sorted.push_back(v);
                colours.push_back(static_cast<int>(c) + 1);
            }
        }
    }

    void Expand(const std::vector<int>& candidates) {
        nodes_ += 1 + static_cast<std::int64_t>(candidates.size());
        if (nodes_ > max_nodes_) return;
        std::vector<int> sorted, colours;
        ColourSort(candidates, sorted, colours);
        for (int i = static_cast<int>(sorted.size()) - 1; i >= 0; --i) {
            if (current_.size() + colours[i] <= best_.size()) return;  // bound
            const int v = sorted[i];
            current_.push_back(v);
            std::vector<int> next;
            for (int k = 0; k < i; ++k) {
                if (adjacent_[Index(v, sorted[k])]) next.push_back(sorted[k]);
            }
            if (next.empty()) {
                if (current_.size() > best_.size()) best_ = current_;
            } else {
                Expand(next);
            }
            current_.pop_back();
            if (nodes_ > max_nodes_) return;
        }
    }

    int n_;
    std::vector<std::uint8_t> adjacent_;
    std::int64_t max_nodes_;
    std::int64_t nodes_ = 0;
    std::vector<int> current_;
    std::vector<int> best_;
};

}  // namespace

std::vector<int> MaximumClique(const std::vector<std::vector<int>>& adjacency,
                               std::int64_t max_nodes, std::int64_t* nodes, bool* exact,
                               const std::vector<int>& seed) {
    CliqueSearch search(adjacency, max_nodes);
    search.Seed(seed);
    std::vector<int> clique = search.Run();
    std::sort(clique.begin(), clique.end());
    if (nodes != nullptr) *nodes = search.nodes();
    if (exact != nullptr) *exact = search.exact();
    return clique;
}

}  // namespace certislam::slam
