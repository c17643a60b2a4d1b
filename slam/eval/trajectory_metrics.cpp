// ATE and RPE as evo computes them (evo/core/sync.py, evo/core/metrics.py), in Eigen.
#include "slam/eval/trajectory_metrics.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace certislam::slam {
namespace {

double Rmse(const std::vector<double>& errors) {
    if (errors.empty()) return 0.0;
    double sum = 0.0;
    for (double e : errors) sum += e * e;
    return std::sqrt(sum / static_cast<double>(errors.size()));
}

/// Index of the stamp in `sorted` nearest to `stamp` (sorted non-empty, ascending).
size_t Nearest(const std::vector<double>& sorted, double stamp) {
    const auto it = std::lower_bound(sorted.begin(), sorted.end(), stamp);
    if (it == sorted.begin()) return 0;
    if (it == sorted.end()) return sorted.size() - 1;
    const size_t hi = static_cast<size_t>(it - sorted.begin());
    return (stamp - sorted[hi - 1] <= sorted[hi] - stamp) ? hi - 1 : hi;
}

std::vector<double> RpeErrors(const AssociatedPoses& poses, int delta) {
    std::vector<double> errors;
    for (size_t k = 0; k + static_cast<size_t>(delta) < poses.gt.size(); ++k) {
        const size_t l = k + static_cast<size_t>(delta);
        const Eigen::Isometry3d gt_rel = poses.gt[k].inverse() * poses.gt[l];
        const Eigen::Isometry3d est_rel = poses.est[k].inverse() * poses.est[l];
        errors.push_back((gt_rel.inverse() * est_rel).translation().norm());
    }
    return errors;
}

}  // namespace

void AssociationConfig::Validate() const {
    if (!(max_diff_s >= 0.0) || !std::isfinite(max_diff_s)) {
        throw std::invalid_argument("AssociationConfig.max_diff_s = " + std::to_string(max_diff_s) +
                                    ": must be finite and >= 0");
    }
}

AssociatedPoses Associate(const Trajectory& gt, const Trajectory& est,
                          const AssociationConfig& config) {
    config.Validate();
    AssociatedPoses out;
    if (config.by_index) {
        const size_t n = std::min(gt.size(), est.size());
        for (size_t k = 0; k < n; ++k) {
            out.gt.push_back(gt[k].T_world_body);
            out.est.push_back(est[k].T_world_body);
        }
        return out;
    }
    const bool gt_shorter = gt.size() <= est.size();
    const Trajectory& shorter = gt_shorter ? gt : est;
    Trajectory longer = gt_shorter ? est : gt;
    if (longer.empty()) return out;
    std::stable_sort(longer.begin(), longer.end(), [](const StampedPose& a, const StampedPose& b) {
        return a.stamp_s < b.stamp_s;
    });
    std::vector<double> stamps;
    for (const auto& p : longer) stamps.push_back(p.stamp_s);
    for (const auto& p : shorter) {
        const size_t k = Nearest(stamps, p.stamp_s);
        if (std::abs(stamps[k] - p.stamp_s) > config.max_diff_s) continue;
        out.gt.push_back(gt_shorter ? p.T_world_body : longer[k].T_world_body);
        out.est.push_back(gt_shorter ? longer[k].T_world_body : p.T_world_body);
    }
    return out;
}

std::optional<Eigen::Isometry3d> AlignSE3(const std::vector<AssociatedPoses>& trajectories) {
    Eigen::Index n = 0;
    for (const auto& t : trajectories) n += static_cast<Eigen::Index>(t.gt.size());
    if (n == 0) return std::nullopt;
    Eigen::Matrix3Xd src(3, n), dst(3, n);
    Eigen::Index k = 0;
    for (const auto& t : trajectories) {
        for (size_t i = 0; i < t.gt.size(); ++i, ++k) {
            src.col(k) = t.est[i].translation();
            dst.col(k) = t.gt[i].translation();
        }
    }
    Eigen::Isometry3d T_gt_est = Eigen::Isometry3d::Identity();
    if (n == 1) {
        T_gt_est.translation() = dst.col(0) - src.col(0);
        return T_gt_est;
    }
    T_gt_est.matrix() = Eigen::umeyama(src, dst, false);
    return T_gt_est;
}

std::vector<double> AteErrors(const AssociatedPoses& poses, const Eigen::Isometry3d& T_gt_est) {
    std::vector<double> errors;
    errors.reserve(poses.gt.size());
    for (size_t i = 0; i < poses.gt.size(); ++i) {
        errors.push_back(
            (poses.gt[i].translation() - T_gt_est * poses.est[i].translation()).norm());
    }
    return errors;
}

double AteRmse(const AssociatedPoses& poses, const Eigen::Isometry3d& T_gt_est) {
    return Rmse(AteErrors(poses, T_gt_est));
}

double RpeRmse(const AssociatedPoses& poses, int delta) { return Rmse(RpeErrors(poses, delta)); }

TeamErrors EvaluateTeam(const std::vector<AssociatedPoses>& robots, bool align) {
    TeamErrors team;
    const auto joint = AlignSE3(robots);
    if (!joint) {
        team.status = TeamErrors::Status::kNoPairs;
        return team;
    }
    if (align) team.T_gt_est = *joint;
    std::vector<double> ate_all, rpe_all;
    for (const auto& poses : robots) {
        TrajectoryErrors e;
        e.pairs = static_cast<int>(poses.gt.size());
        const auto ate = AteErrors(poses, team.T_gt_est);
        const auto rpe = RpeErrors(poses, 1);
        e.ate_rmse = Rmse(ate);
        e.rpe_rmse = Rmse(rpe);
        const auto own = align ? AlignSE3({poses}) : std::nullopt;
        e.ate_rmse_own = own ? AteRmse(poses, *own) : e.ate_rmse;
        ate_all.insert(ate_all.end(), ate.begin(), ate.end());
        rpe_all.insert(rpe_all.end(), rpe.begin(), rpe.end());
        team.pairs += e.pairs;
        team.robots.push_back(e);
    }
    team.ate_rmse = Rmse(ate_all);
    team.rpe_rmse = Rmse(rpe_all);
    return team;
}

AlignedTeam AlignTeam(const std::vector<Trajectory>& gt, const std::vector<Trajectory>& est) {
    std::vector<AssociatedPoses> pairs;
    for (size_t r = 0; r < est.size(); ++r) pairs.push_back(Associate(gt[r], est[r], {}));
    const TeamErrors errors = EvaluateTeam(pairs, true);
    AlignedTeam out;
    for (const auto& e : errors.robots) out.ate_rmse.push_back(e.ate_rmse);
    out.aligned = est;
    for (auto& traj : out.aligned) {
        for (auto& p : traj) p.T_world_body = errors.T_gt_est * p.T_world_body;
    }
    return out;
}

}  // namespace certislam::slam
