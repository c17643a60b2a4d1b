// Trajectory errors with evo's conventions: ATE RMSE after Umeyama SE(3) alignment, and RPE.
#pragma once

#include <optional>
#include <vector>

#include "slam/core/trajectory.h"

namespace certislam::slam {

/// How estimated poses are matched to ground-truth poses.
struct AssociationConfig {
    bool by_index = false;     ///< match pose k to pose k (KITTI); else by time stamp (TUM)
    double max_diff_s = 0.01;  ///< largest stamp difference of a match, s (evo's default)

    /// Throws std::invalid_argument naming the field when a value is out of range.
    void Validate() const;
};

/// Ground-truth and estimated poses matched one to one, in stamp order.
struct AssociatedPoses {
    std::vector<Eigen::Isometry3d> gt;   ///< T_world_body of the reference
    std::vector<Eigen::Isometry3d> est;  ///< T_world_body of the estimate (its own world frame)
};

/// Matches poses like evo's `associate_trajectories`: for every pose of the shorter trajectory
/// the nearest stamp of the longer one, kept when within max_diff_s (by index: the common
/// prefix). Matches keep the order of the shorter trajectory.
AssociatedPoses Associate(const Trajectory& gt, const Trajectory& est,
                          const AssociationConfig& config);

/// The rigid transform T_gt_est minimising sum ||p_gt - T p_est||^2 over all pairs of all
/// trajectories at once (Umeyama without scale; joint alignment of a team). std::nullopt when
/// there are no pairs.
std::optional<Eigen::Isometry3d> AlignSE3(const std::vector<AssociatedPoses>& trajectories);

/// Absolute trajectory error: RMSE of ||t_gt - (T_gt_est * T_est).t|| over the pairs (m).
double AteRmse(const AssociatedPoses& poses, const Eigen::Isometry3d& T_gt_est);

/// Translation errors behind AteRmse, one per pair (m).
std::vector<double> AteErrors(const AssociatedPoses& poses, const Eigen::Isometry3d& T_gt_est);

/// Relative pose error, translation part, evo's definition with delta frames:
/// E_k = (G_k^-1 G_k+delta)^-1 (P_k^-1 P_k+delta); RMSE of ||t(E_k)|| (m). 0 with < 2 pairs.
double RpeRmse(const AssociatedPoses& poses, int delta = 1);

/// Errors of one robot's trajectory.
struct TrajectoryErrors {
    int pairs = 0;              ///< associated pose pairs
    double ate_rmse = 0.0;      ///< ATE RMSE under the team's joint alignment, m
    double ate_rmse_own = 0.0;  ///< ATE RMSE when this robot is aligned on its own, m
    double rpe_rmse = 0.0;      ///< RPE RMSE (translation, delta 1 frame), m
};

/// Errors of a team: joint figures and one entry per robot.
struct TeamErrors {
    enum class Status { kOk, kNoPairs };
    Status status = Status::kOk;
    int pairs = 0;          ///< associated pairs over all robots
    double ate_rmse = 0.0;  ///< ATE RMSE over all pairs under the joint alignment, m
    double rpe_rmse = 0.0;  ///< RPE RMSE over all robots' consecutive pairs, m
    Eigen::Isometry3d T_gt_est = Eigen::Isometry3d::Identity();  ///< the joint alignment
    std::vector<TrajectoryErrors> robots;                        ///< per robot, in input order
};

/// Evaluates a team: with `align` the estimates are aligned once, jointly (one T_gt_est for
/// all robots), and each robot also on its own; without it T_gt_est is the identity.
TeamErrors EvaluateTeam(const std::vector<AssociatedPoses>& robots, bool align);

/// A team's estimates scored under one joint SE(3) alignment.
struct AlignedTeam {
    std::vector<double> ate_rmse;     ///< [robot] ATE RMSE under the joint alignment, m
    std::vector<Trajectory> aligned;  ///< [robot] the estimate mapped by T_gt_est (gt frame)
};

/// Associates est[r] with gt[r] by stamp (default AssociationConfig), aligns the whole team
/// with one T_gt_est (EvaluateTeam with align) and returns each robot's ATE RMSE and the
/// estimates moved into the ground-truth frame. `gt` has at least est.size() trajectories.
AlignedTeam AlignTeam(const std::vector<Trajectory>& gt, const std::vector<Trajectory>& est);

}  // namespace certislam::slam
