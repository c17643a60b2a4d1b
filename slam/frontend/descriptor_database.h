// A growing database of Scan Context descriptors (this robot's and its peers'), queried by
// ring-key k-nearest-neighbours and re-ranked by the column-shift distance.
#pragma once

#include <cstddef>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <vector>

#include "slam/core/pose_graph.h"
#include "slam/frontend/scan_context.h"

namespace certislam::slam {

/// Settings of candidate retrieval.
struct DescriptorDatabaseConfig {
    int num_candidates = 10;     ///< ring-key nearest neighbours re-ranked per query, >= 1
    int exclude_recent = 50;     ///< own keyframes with |index - query index| < this are no
                                 ///< candidates (they are neighbours in time, not loops), >= 0
    double max_distance = 0.15;  ///< a candidate is returned only below this SC distance, (0, 1]
    bool fast_search = true;     ///< use the sector-key fast distance instead of all shifts
    double fast_search_ratio = 0.1;  ///< +-ratio*N_s shifts for the fast distance, (0, 0.5]

    /// Throws std::invalid_argument naming the field, its value and the rule.
    void Validate() const;
};

/// A retrieved place: the stored keyframe and how the query aligns to it.
struct PlaceMatch {
    PoseId id;                     ///< the stored keyframe (robot, index)
    ScanContextMatch match;        ///< distance, shift, yaw (T_candidate_query ~ Rz(yaw))
    double ring_key_distance = 0;  ///< Euclidean ring-key distance (the k-d tree's metric)
};

/// Descriptors keyed by PoseId in a k-d tree over ring keys (nanoflann's dynamic adaptor: a
/// log-structured set of static trees, so an insertion rebuilds O(log n) small trees, not all).
class DescriptorDatabase {
  public:
    /// An empty database; `config` is validated. All descriptors must share N_r x N_s.
    explicit DescriptorDatabase(DescriptorDatabaseConfig config = {});
    ~DescriptorDatabase();
    DescriptorDatabase(DescriptorDatabase&&) noexcept;
    DescriptorDatabase& operator=(DescriptorDatabase&&) noexcept;

    /// Stores a descriptor. Returns false (and stores nothing) if `id` is already stored.
    /// Descriptors of another shape than the first one stored are a programmer error.
    bool Add(const PoseId& id, ScanContext descriptor);

    /// Number of stored descriptors.
    std::size_t size() const;

    /// The stored descriptor of `id`, or nullptr.
    const ScanContext* Find(const PoseId& id) const;

    /// Candidates for a query keyframe `query_id` (it need not be stored): the num_candidates
    /// nearest ring keys among entries passing `accept` (all when empty) and not recent own
    /// keyframes, scored by the SC distance; those under max_distance, best first.
    std::vector<PlaceMatch> Query(const PoseId& query_id, const ScanContext& descriptor,
                                  const std::function<bool(const PoseId&)>& accept = {}) const;

    /// The best candidate of Query, if any.
    std::optional<PlaceMatch> Detect(const PoseId& query_id, const ScanContext& descriptor,
                                     const std::function<bool(const PoseId&)>& accept = {}) const;

    /// The settings in use.
    const DescriptorDatabaseConfig& config() const { return config_; }

  private:
    struct Index;
    DescriptorDatabaseConfig config_;
    std::vector<PoseId> ids_;               ///< entry -> id
    std::vector<ScanContext> descriptors_;  ///< entry -> descriptor
    std::map<PoseId, std::size_t> by_id_;   ///< id -> entry
    std::unique_ptr<Index> index_;          ///< ring keys and the k-d trees over them
};

}  // namespace certislam::slam
