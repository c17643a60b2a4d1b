// DescriptorDatabase: ring-key k-d trees (nanoflann dynamic adaptor) + column-shift re-ranking.
#include "slam/frontend/descriptor_database.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <nanoflann.hpp>
#include <stdexcept>
#include <string>

#include "slam/core/check.h"

namespace certislam::slam {
namespace {

[[noreturn]] void Invalid(const std::string& field, double value, const std::string& rule) {
    throw std::invalid_argument("DescriptorDatabaseConfig." + field + " = " +
                                std::to_string(value) + ": must be " + rule);
}

// The ring keys as nanoflann's dataset: point i is keys[i*dim .. i*dim+dim).
struct RingKeys {
    std::vector<float> keys;
    std::size_t dim = 0;

    std::size_t kdtree_get_point_count() const { return dim == 0 ? 0 : keys.size() / dim; }
    float kdtree_get_pt(std::size_t i, std::size_t d) const { return keys[i * dim + d]; }
    template <class Box>
    bool kdtree_get_bbox(Box&) const {
        return false;
    }
};

// k nearest neighbours among the entries `accept(i)` admits (nanoflann's ResultSet interface):
// filtering inside the search keeps k real candidates even when the k nearest ring keys are
// all recent own keyframes.
template <typename Accept>
class FilteredKnn {
  public:
    using DistanceType = float;
    using IndexType = std::size_t;

    FilteredKnn(std::size_t capacity, Accept accept) : capacity_(capacity), accept_(accept) {}

    std::size_t size() const { return found_.size(); }
    bool full() const { return found_.size() == capacity_; }
    float worstDist() const {
        return full() ? found_.back().first : std::numeric_limits<float>::max();
    }
    bool addPoint(float dist, std::size_t index) {
        if (!accept_(index)) return true;
        const auto pos =
            std::upper_bound(found_.begin(), found_.end(), std::make_pair(dist, index));
        found_.insert(pos, {dist, index});
        if (found_.size() > capacity_) found_.pop_back();
        return true;
    }
    /// (squared distance, entry) pairs, nearest first.
    const std::vector<std::pair<float, std::size_t>>& found() const { return found_; }

  private:
    std::size_t capacity_;
    Accept accept_;
    std::vector<std::pair<float, std::size_t>> found_;
};

using Tree =
    nanoflann::KDTreeSingleIndexDynamicAdaptor<nanoflann::L2_Simple_Adaptor<float, RingKeys>,
                                               RingKeys, -1, std::size_t>;

}  // namespace

struct DescriptorDatabase::Index {
    RingKeys ring_keys;
    std::unique_ptr<Tree> tree;
};

void DescriptorDatabaseConfig::Validate() const {
    if (num_candidates < 1) Invalid("num_candidates", num_candidates, ">= 1");
    if (exclude_recent < 0) Invalid("exclude_recent", exclude_recent, ">= 0");
    if (!(max_distance > 0.0 && max_distance <= 1.0)) {
        Invalid("max_distance", max_distance, "in (0, 1]");
    }
    if (!(fast_search_ratio > 0.0 && fast_search_ratio <= 0.5)) {
        Invalid("fast_search_ratio", fast_search_ratio, "in (0, 0.5]");
    }
}

DescriptorDatabase::DescriptorDatabase(DescriptorDatabaseConfig config)
    : config_(config), index_(std::make_unique<Index>()) {
    config_.Validate();
}

DescriptorDatabase::~DescriptorDatabase() = default;
DescriptorDatabase::DescriptorDatabase(DescriptorDatabase&&) noexcept = default;
DescriptorDatabase& DescriptorDatabase::operator=(DescriptorDatabase&&) noexcept = default;

bool DescriptorDatabase::Add(const PoseId& id, ScanContext descriptor) {
    if (by_id_.contains(id)) return false;
    const auto dim = static_cast<std::size_t>(descriptor.ring_key.size());
    CERTISLAM_CHECK(dim > 0);
    if (!descriptors_.empty()) {
        CERTISLAM_CHECK(descriptor.bins.rows() == descriptors_.front().bins.rows() &&
                        descriptor.bins.cols() == descriptors_.front().bins.cols());
    }
    Index& index = *index_;
    if (!index.tree) {
        index.ring_keys.dim = dim;
        index.tree = std::make_unique<Tree>(static_cast<int>(dim), index.ring_keys,
                                            nanoflann::KDTreeSingleIndexAdaptorParams(10));
    }
    const std::size_t entry = ids_.size();
    index.ring_keys.keys.insert(index.ring_keys.keys.end(), descriptor.ring_key.data(),
                                descriptor.ring_key.data() + dim);
    ids_.push_back(id);
    descriptors_.push_back(std::move(descriptor));
    by_id_.emplace(id, entry);
    index.tree->addPoints(entry, entry);  // merges into O(log n) trees, never a full rebuild
    return true;
}

std::size_t DescriptorDatabase::size() const { return ids_.size(); }

const ScanContext* DescriptorDatabase::Find(const PoseId& id) const {
    const auto it = by_id_.find(id);
    return it == by_id_.end() ? nullptr : &descriptors_[it->second];
}

std::vector<PlaceMatch> DescriptorDatabase::Query(
    const PoseId& query_id, const ScanContext& descriptor,
    const std::function<bool(const PoseId&)>& accept) const {
    std::vector<PlaceMatch> out;
    if (ids_.empty()) return out;
    CERTISLAM_CHECK(static_cast<std::size_t>(descriptor.ring_key.size()) == index_->ring_keys.dim);
    auto admit = [&](std::size_t entry) {
        const PoseId& id = ids_[entry];
        if (id == query_id) return false;
        if (id.robot == query_id.robot &&
            std::abs(id.index - query_id.index) < config_.exclude_recent) {
            return false;  // a neighbour in time, not a revisit
        }
        return !accept || accept(id);
    };
    FilteredKnn<decltype(admit)> knn(static_cast<std::size_t>(config_.num_candidates), admit);
    index_->tree->findNeighbors(knn, descriptor.ring_key.data(), nanoflann::SearchParams());
    const int radius = std::max(
        1, static_cast<int>(std::lround(config_.fast_search_ratio * descriptor.bins.cols())));
    for (const auto& [squared, entry] : knn.found()) {
        const ScanContext& stored = descriptors_[entry];
        const ScanContextMatch match = config_.fast_search
                                           ? ScanContextDistanceFast(descriptor, stored, radius)
                                           : ScanContextDistance(descriptor, stored);
        if (match.distance < config_.max_distance) {
            out.push_back({ids_[entry], match, std::sqrt(static_cast<double>(squared))});
        }
    }
    std::sort(out.begin(), out.end(), [](const PlaceMatch& a, const PlaceMatch& b) {
        return a.match.distance < b.match.distance;
    });
    return out;
}

std::optional<PlaceMatch> DescriptorDatabase::Detect(
    const PoseId& query_id, const ScanContext& descriptor,
    const std::function<bool(const PoseId&)>& accept) const {
    auto candidates = Query(query_id, descriptor, accept);
    if (candidates.empty()) return std::nullopt;
    return candidates.front();
}

}  // namespace certislam::slam
