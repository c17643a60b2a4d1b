// First-encounter alignment (DiSCo-SLAM, Huang et al. 2021; the paper's Eq. (1)).
#include "slam/backend/one_time_alignment.h"

#include <deque>

#include "slam/core/check.h"

namespace certislam::slam {

Eigen::Isometry3d FrameFromLoop(const Eigen::Isometry3d& T_odomA_a, const Eigen::Isometry3d& T_a_b,
                                const Eigen::Isometry3d& T_odomB_b) {
    // With a single measurement the argmin of Eq. (1) makes the residual the identity.
    return T_odomA_a * T_a_b * T_odomB_b.inverse();
}

OneTimeAlignmentResult OneTimeAlignment(const std::vector<std::vector<Eigen::Isometry3d>>& odometry,
                                        const std::vector<LoopClosure>& loops) {
    const int num_robots = static_cast<int>(odometry.size());
    OneTimeAlignmentResult result;
    result.T_team_odom.assign(static_cast<size_t>(num_robots), std::nullopt);
    result.aligning_loop.assign(static_cast<size_t>(num_robots), std::nullopt);
    if (num_robots == 0) return result;
    result.T_team_odom[0] = Eigen::Isometry3d::Identity();
    std::deque<int> frontier{0};
    while (!frontier.empty()) {
        const int aligned = frontier.front();
        frontier.pop_front();
        // The first loop (in discovery order) between `aligned` and each unaligned robot.
        for (size_t l = 0; l < loops.size(); ++l) {
            const LoopClosure& loop = loops[l];
            if (!loop.inter_robot()) continue;
            const bool forward = loop.a.robot == aligned;
            if (!forward && loop.b.robot != aligned) continue;
            const int other = forward ? loop.b.robot : loop.a.robot;
            CERTISLAM_CHECK(other >= 0 && other < num_robots);
            if (result.T_team_odom[static_cast<size_t>(other)]) continue;
            const Eigen::Isometry3d& T_odomA_a = odometry[loop.a.robot].at(loop.a.index);
            const Eigen::Isometry3d& T_odomB_b = odometry[loop.b.robot].at(loop.b.index);
            const Eigen::Isometry3d T_odomA_odomB = FrameFromLoop(T_odomA_a, loop.T_a_b, T_odomB_b);
            const Eigen::Isometry3d T_aligned_other =
                forward ? T_odomA_odomB : T_odomA_odomB.inverse();
            result.T_team_odom[static_cast<size_t>(other)] =
                *result.T_team_odom[static_cast<size_t>(aligned)] * T_aligned_other;
            result.aligning_loop[static_cast<size_t>(other)] = static_cast<int>(l);
            frontier.push_back(other);
        }
    }
    result.poses.resize(static_cast<size_t>(num_robots));
    for (int k = 0; k < num_robots; ++k) {
        const Eigen::Isometry3d T =
            result.T_team_odom[static_cast<size_t>(k)].value_or(Eigen::Isometry3d::Identity());
        for (const auto& T_odom_sensor : odometry[static_cast<size_t>(k)]) {
            result.poses[static_cast<size_t>(k)].push_back(T * T_odom_sensor);
        }
    }
    return result;
}

}  // namespace certislam::slam
