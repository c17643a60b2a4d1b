// Exact maximum clique by branch and bound with a greedy-colouring bound (Tomita & Seki 2003,
// MCQ) on bit sets (San Segundo et al. 2011, BBMC): a candidate set is a row of 64-bit words, so
// colouring and the candidates' intersection with a vertex's neighbours are word operations.
#include "slam/frontend/max_clique.h"

#include <algorithm>
#include <bit>
#include <cstdint>
#include <numeric>
#include <vector>

namespace certislam::slam {
namespace {

using Word = std::uint64_t;
constexpr int kBits = 64;

class CliqueSearch {
  public:
    CliqueSearch(const std::vector<std::vector<int>>& adjacency, std::int64_t max_nodes)
        : n_(static_cast<int>(adjacency.size())),
          words_((n_ + kBits - 1) / kBits),
          vertex_of_(static_cast<size_t>(n_)),
          bit_of_(static_cast<size_t>(n_)),
          rows_(static_cast<size_t>(n_) * words_, 0),
          max_nodes_(max_nodes) {
        // Bits in order of non-increasing degree (ties: lower vertex first), so the greedy
        // colouring, which takes bits in order, colours well-connected vertices first.
        std::vector<int> degree(static_cast<size_t>(n_), 0);
        for (int u = 0; u < n_; ++u) {
            for (const int v : adjacency[u]) degree[u] += (v != u) ? 1 : 0;
        }
        std::iota(vertex_of_.begin(), vertex_of_.end(), 0);
        std::stable_sort(vertex_of_.begin(), vertex_of_.end(),
                         [&](int a, int b) { return degree[a] > degree[b]; });
        for (int b = 0; b < n_; ++b) bit_of_[vertex_of_[b]] = b;
        for (int u = 0; u < n_; ++u) {
            for (const int v : adjacency[u]) {
                if (v == u) continue;
                Set(Row(bit_of_[u]), bit_of_[v]);
                Set(Row(bit_of_[v]), bit_of_[u]);
            }
        }
    }

    /// Starts from `clique` when it is one (distinct vertices, pairwise adjacent).
    void Seed(const std::vector<int>& clique) {
        std::vector<int> bits;
        for (size_t i = 0; i < clique.size(); ++i) {
            if (clique[i] < 0 || clique[i] >= n_) return;
            const int b = bit_of_[clique[i]];
            for (const int c : bits) {
                if (!Test(Row(b), c)) return;  // also a repeated vertex: no self-loops
            }
            bits.push_back(b);
        }
        best_ = bits;
    }

    std::vector<int> Run() {
        std::vector<Word> all(static_cast<size_t>(words_), 0);
        for (int b = 0; b < n_; ++b) Set(all.data(), b);
        Expand(all);
        std::vector<int> clique;
        for (const int b : best_) clique.push_back(vertex_of_[b]);
        return clique;
    }

    std::int64_t nodes() const { return nodes_; }
    bool exact() const { return nodes_ <= max_nodes_; }

  private:
    Word* Row(int b) { return rows_.data() + static_cast<size_t>(b) * words_; }
    const Word* Row(int b) const { return rows_.data() + static_cast<size_t>(b) * words_; }
    static void Set(Word* row, int b) { row[b / kBits] |= Word{1} << (b % kBits); }
    static void Reset(Word* row, int b) { row[b / kBits] &= ~(Word{1} << (b % kBits)); }
    static bool Test(const Word* row, int b) { return (row[b / kBits] >> (b % kBits)) & 1; }
    int Count(const std::vector<Word>& set) const {
        int count = 0;
        for (const Word w : set) count += std::popcount(w);
        return count;
    }

    // Greedy colouring of `candidates` in bit order: colour classes are independent sets, so a
    // clique takes at most one vertex of each. `order` gets the vertices by colour (1-based in
    // `colours`), the bound of MCQ.
    void ColourSort(const std::vector<Word>& candidates, std::vector<int>& order,
                    std::vector<int>& colours) const {
        order.clear();
        colours.clear();
        std::vector<Word> uncoloured = candidates, open(static_cast<size_t>(words_));
        for (int colour = 1;; ++colour) {
            open = uncoloured;
            bool any = false;
            for (int w = 0; w < words_; ++w) {
                while (open[w] != 0) {
                    const int b = w * kBits + std::countr_zero(open[w]);
                    any = true;
                    order.push_back(b);
                    colours.push_back(colour);
                    Reset(uncoloured.data(), b);
                    const Word* row = Row(b);
                    open[w] &= ~(Word{1} << (b % kBits));
                    for (int x = w; x < words_; ++x) open[x] &= ~row[x];  // neighbours later
                }
            }
            if (!any) return;
        }
    }

    void Expand(std::vector<Word> candidates) {
        nodes_ += 1 + Count(candidates);
        if (nodes_ > max_nodes_) return;
        std::vector<int> order, colours;
        ColourSort(candidates, order, colours);
        std::vector<Word> next(static_cast<size_t>(words_));
        for (int i = static_cast<int>(order.size()) - 1; i >= 0; --i) {
            if (current_.size() + colours[i] <= best_.size()) return;  // bound
            const int b = order[i];
            current_.push_back(b);
            const Word* row = Row(b);
            bool empty = true;
            for (int w = 0; w < words_; ++w) {
                next[w] = candidates[w] & row[w];
                empty = empty && next[w] == 0;
            }
            if (empty) {
                if (current_.size() > best_.size()) best_ = current_;
            } else {
                Expand(next);
            }
            current_.pop_back();
            Reset(candidates.data(), b);  // its cliques are searched
            if (nodes_ > max_nodes_) return;
        }
    }

    int n_;
    int words_;
    std::vector<int> vertex_of_;  // bit -> vertex
    std::vector<int> bit_of_;     // vertex -> bit
    std::vector<Word> rows_;      // neighbours of each bit, words_ words each
    std::int64_t max_nodes_;
    std::int64_t nodes_ = 0;
    std::vector<int> current_;  // bits
    std::vector<int> best_;     // bits
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
