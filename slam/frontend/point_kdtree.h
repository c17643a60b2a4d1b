// A static 3-D k-d tree (nanoflann) over a PointCloud, for nearest-neighbour queries.
#pragma once

#include <cstddef>
#include <memory>
#include <nanoflann.hpp>
#include <utility>
#include <vector>

#include "slam/core/keyframe.h"

namespace certislam::slam {

/// Nearest neighbours in a cloud that outlives the tree. Build O(n log n), query O(log n).
class PointKdTree {
  public:
    /// Builds the tree over `cloud` (kept by reference: it must outlive the tree).
    explicit PointKdTree(const PointCloud& cloud)
        : adaptor_{&cloud},
          tree_(
              std::make_unique<Tree>(3, adaptor_, nanoflann::KDTreeSingleIndexAdaptorParams(10))) {
    }                                          // nanoflann builds the index in its constructor
    PointKdTree(const PointKdTree&) = delete;  ///< the tree refers to adaptor_ by address
    PointKdTree& operator=(const PointKdTree&) = delete;

    /// The k nearest points to `q`: fills `indices` and squared distances, nearest first.
    /// Returns how many were found (fewer than k only when the cloud is smaller).
    std::size_t Knn(const Eigen::Vector3f& q, std::size_t k, std::vector<std::size_t>& indices,
                    std::vector<float>& squared) const {
        indices.resize(k);
        squared.resize(k);
        const std::size_t found = tree_->knnSearch(q.data(), k, indices.data(), squared.data());
        indices.resize(found);
        squared.resize(found);
        return found;
    }

    /// Every point within sqrt(squared_radius) of `q` as (index, squared distance), nearest first.
    std::size_t Within(const Eigen::Vector3f& q, float squared_radius,
                       std::vector<std::pair<std::size_t, float>>& found) const {
        found.clear();
        return tree_->radiusSearch(q.data(), squared_radius, found, nanoflann::SearchParams());
    }

    /// The nearest point's index and squared distance; false when the cloud is empty.
    bool Nearest(const Eigen::Vector3f& q, std::size_t& index, float& squared) const {
        if (adaptor_.cloud->empty()) return false;
        return tree_->knnSearch(q.data(), 1, &index, &squared) == 1;
    }

  private:
    struct Adaptor {
        const PointCloud* cloud;
        std::size_t kdtree_get_point_count() const { return cloud->size(); }
        float kdtree_get_pt(std::size_t i, std::size_t d) const {
            return (*cloud)[i][static_cast<int>(d)];
        }
        template <class Box>
        bool kdtree_get_bbox(Box&) const {
            return false;
        }
    };
    using Tree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, Adaptor>,
                                                     Adaptor, 3, std::size_t>;
    Adaptor adaptor_;
    std::unique_ptr<Tree> tree_;
};

}  // namespace certislam::slam
