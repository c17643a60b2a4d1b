// The DiSCo-SLAM-style baseline: one rigid transform per robot pair from their first verified
// inter-robot loop closure; later inter-robot loops are not used (paper Eq. (1)).
#pragma once

#include <optional>
#include <vector>

#include "slam/core/loop_closure.h"

namespace certislam::slam {

/// T_a_b = argmin_T || T T_a T_b^-1 || for one loop: robot b's odometry frame in robot a's,
/// from the loop's two odometry poses and its measured relative pose:
/// T_odomA_odomB = T_odomA_a * T_a_b * T_odomB_b^-1.
Eigen::Isometry3d FrameFromLoop(const Eigen::Isometry3d& T_odomA_a, const Eigen::Isometry3d& T_a_b,
                                const Eigen::Isometry3d& T_odomB_b);

/// What the one-time alignment gave.
struct OneTimeAlignmentResult {
    /// T_team_odom[k]: robot k's odometry frame in the team frame (robot 0's odometry frame);
    /// std::nullopt for robots never connected to robot 0 (they keep their own frame).
    std::vector<std::optional<Eigen::Isometry3d>> T_team_odom;
    /// Index into the loop list of the loop that aligned robot k (std::nullopt for 0/unaligned).
    std::vector<std::optional<int>> aligning_loop;
    /// Poses T_team_sensor[robot][keyframe]: odometry mapped by T_team_odom (own frame if none).
    std::vector<std::vector<Eigen::Isometry3d>> poses;
};

/// Aligns every robot to robot 0 by first encounters. `odometry[k][i]` is T_odom_sensor of
/// robot k's keyframe i; `loops` are verified closures in the order they were found (the first
/// inter-robot loop of a pair is the first in this order). Robot 0 anchors the team; robot b is
/// aligned through the first loop joining it to an already aligned robot (breadth first over
/// the pairs' first loops, so chains 0-1-2 work). Intra-robot loops are ignored.
OneTimeAlignmentResult OneTimeAlignment(const std::vector<std::vector<Eigen::Isometry3d>>& odometry,
                                        const std::vector<LoopClosure>& loops);

}  // namespace certislam::slam
