// Incremental pairwise consistency maximisation for one loop matcher: verified loops arrive one
// at a time with the odometry poses of their ends only (a peer's keyframes come with the clouds
// it sends); the consistent set (exact maximum clique per robot pair, intra-robot loops also
// checked against odometry) is re-evaluated on each arrival, so an earlier loop may drop out.
#pragma once

#include <Eigen/Geometry>
#include <map>
#include <utility>
#include <vector>

#include "slam/core/loop_closure.h"
#include "slam/core/pose_graph.h"
#include "slam/frontend/pcm.h"
#include "slam/frontend/registration.h"

namespace certislam::slam {

/// Odometry of one keyframe as PCM needs it.
struct KeyframeOdometry {
    Eigen::Isometry3d T_odom = Eigen::Isometry3d::Identity();  ///< T_odom_sensor
    double travelled_m = 0.0;  ///< odometry distance travelled up to this keyframe
};

/// The loops PCM keeps out of those verified so far, re-evaluated as new ones arrive.
class IncrementalPcm {
  public:
    /// `config` validated (throws std::invalid_argument).
    explicit IncrementalPcm(PcmConfig config);

    /// Records the odometry of keyframe `id` (the first value given is kept).
    void SetOdometry(const PoseId& id, const KeyframeOdometry& odometry);
    /// True once the odometry of `id` is known.
    bool HasOdometry(const PoseId& id) const { return odometry_.count(id) > 0; }

    /// Adds a verified loop; false (and nothing changes) when the odometry of an end is unknown
    /// or a loop with the same ends was added before. An intra-robot loop that disagrees with
    /// the odometry between its ends is recorded as rejected and never kept.
    bool Add(const LoopClosure& loop, const Information6& information);

    /// The consistent loops now: per robot pair the exact maximum clique of the pairwise
    /// consistency graph when it has at least min_clique_size members; in arrival order.
    std::vector<LoopClosure> Consistent() const;

    /// Verified loops added so far.
    int Size() const { return static_cast<int>(loops_.size()); }
    /// Intra-robot loops rejected by their odometry check.
    int RejectedByOdometry() const { return rejected_by_odometry_; }
    /// False when some clique search hit the node budget (best clique kept).
    bool Exact() const { return exact_; }

  private:
    struct Entry {
        LoopClosure loop;
        PcmMeasurement measurement;  ///< oriented a.robot <= b.robot
        bool odometry_ok = true;
    };
    using Group = std::pair<int, int>;

    bool OdometryAgrees(const PcmMeasurement& m) const;
    double Pairwise(const PcmMeasurement& i, const PcmMeasurement& j) const;

    PcmConfig config_;
    std::map<PoseId, KeyframeOdometry> odometry_;
    std::vector<Entry> loops_;
    std::map<Group, std::vector<int>> groups_;                  ///< entries with odometry_ok
    std::map<Group, std::vector<std::vector<int>>> adjacency_;  ///< per group, local indices
    int rejected_by_odometry_ = 0;
    mutable bool exact_ = true;
    /// Each group's last maximum clique (member positions): the next search starts from it, as
    /// a group only gains members and their pairwise tests never change.
    mutable std::map<Group, std::vector<int>> last_clique_;
};

}  // namespace certislam::slam
