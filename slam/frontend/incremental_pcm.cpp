// Incremental PCM: the pairwise consistency graph grows by one row per verified loop (odometry
// never changes once known, so old pairs are not re-tested); each clique search starts from the
// group's last maximum clique (on a tie the earlier clique stays).
#include "slam/frontend/incremental_pcm.h"

#include <algorithm>

#include "slam/core/se3.h"

namespace certislam::slam {

IncrementalPcm::IncrementalPcm(PcmConfig config) : config_(config) { config_.Validate(); }

void IncrementalPcm::SetOdometry(const PoseId& id, const KeyframeOdometry& odometry) {
    odometry_.emplace(id, odometry);
}

bool IncrementalPcm::OdometryAgrees(const PcmMeasurement& m) const {
    // Dense odometry of the robot up to the later end (the matcher's own robot has it all):
    // the same test as RejectOutliersPcm's, on a one-measurement problem.
    const int r = m.a.robot, last = std::max(m.a.index, m.b.index);
    std::vector<std::vector<Eigen::Isometry3d>> odometry(static_cast<size_t>(r) + 1);
    for (int k = 0; k <= last; ++k) {
        const auto it = odometry_.find({r, k});
        if (it == odometry_.end()) return true;  // not dense: the clique test alone decides
        odometry[static_cast<size_t>(r)].push_back(it->second.T_odom);
    }
    PcmConfig single = config_;
    single.min_clique_size = 1;
    return RejectOutliersPcm({m}, odometry, single).inlier.front();
}

double IncrementalPcm::Pairwise(const PcmMeasurement& i, const PcmMeasurement& j) const {
    // Only the four ends' odometry is known (and needed): renumber them densely per robot.
    const int robots = std::max(i.a.robot, i.b.robot) + 1;
    std::vector<std::vector<Eigen::Isometry3d>> odometry(static_cast<size_t>(robots));
    std::vector<std::vector<double>> travelled(static_cast<size_t>(robots));
    const auto local = [&](const PoseId& id) {
        const KeyframeOdometry& o = odometry_.at(id);
        odometry[static_cast<size_t>(id.robot)].push_back(o.T_odom);
        travelled[static_cast<size_t>(id.robot)].push_back(o.travelled_m);
        return PoseId{id.robot,
                      static_cast<int>(odometry[static_cast<size_t>(id.robot)].size()) - 1};
    };
    PcmMeasurement li = i, lj = j;
    li.a = local(i.a);
    li.b = local(i.b);
    lj.a = local(j.a);
    lj.b = local(j.b);
    return PairwiseMahalanobis2(li, lj, odometry, travelled, config_);
}

bool IncrementalPcm::Add(const LoopClosure& loop, const Information6& information) {
    if (!HasOdometry(loop.a) || !HasOdometry(loop.b)) return false;
    for (const Entry& e : loops_) {
        if (e.loop.a == loop.a && e.loop.b == loop.b) return false;
    }
    Entry entry{loop, {loop.a, loop.b, loop.T_a_b, information}, true};
    if (loop.a.robot > loop.b.robot) {
        // Orient like RejectOutliersPcm: a.robot <= b.robot, the inverse measurement's
        // information by the adjoint of T_a_b (right perturbation).
        const Eigen::Isometry3d T_b_a = loop.T_a_b.inverse();
        entry.measurement = PcmMeasurement{loop.b, loop.a, T_b_a, information};
        const Matrix6 ad = Adjoint(loop.T_a_b);
        const Matrix6 ad_inv = ad.inverse();
        entry.measurement.information = ad_inv.transpose() * information * ad_inv;
    }
    if (!loop.inter_robot() && config_.check_intra_against_odometry) {
        entry.odometry_ok = OdometryAgrees(entry.measurement);
        if (!entry.odometry_ok) ++rejected_by_odometry_;
    }
    const int index = static_cast<int>(loops_.size());
    loops_.push_back(entry);
    if (!entry.odometry_ok) return true;
    const Group group{entry.measurement.a.robot, entry.measurement.b.robot};
    auto& members = groups_[group];
    auto& adjacency = adjacency_[group];
    const int u = static_cast<int>(members.size());
    adjacency.emplace_back();
    for (int v = 0; v < u; ++v) {
        const double m2 = Pairwise(entry.measurement, loops_[members[v]].measurement);
        if (m2 <= config_.chi2_threshold) {
            adjacency[u].push_back(v);
            adjacency[v].push_back(u);
        }
    }
    members.push_back(index);
    return true;
}

std::vector<LoopClosure> IncrementalPcm::Consistent() const {
    std::vector<bool> keep(loops_.size(), false);
    exact_ = true;
    for (const auto& [group, members] : groups_) {
        std::int64_t nodes = 0;
        bool exact = true;
        auto& last = last_clique_[group];
        const auto clique =
            MaximumClique(adjacency_.at(group), config_.max_branch_nodes, &nodes, &exact, last);
        last = clique;
        exact_ = exact_ && exact;
        if (static_cast<int>(clique.size()) < config_.min_clique_size) continue;
        for (int u : clique) keep[static_cast<size_t>(members[static_cast<size_t>(u)])] = true;
    }
    std::vector<LoopClosure> out;
    for (size_t k = 0; k < loops_.size(); ++k) {
        if (keep[k]) out.push_back(loops_[k].loop);
    }
    return out;
}

}  // namespace certislam::slam
