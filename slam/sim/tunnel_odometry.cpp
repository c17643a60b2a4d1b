// Odometry degraded in the simulated city's tunnel.
#include "slam/sim/tunnel_odometry.h"

#include <cmath>

namespace certislam::slam {
namespace {

bool InTunnel(const SimStreets& streets, const Eigen::Vector3d& p) {
    return p.x() > streets.tunnel_x_begin && p.x() < streets.tunnel_x_end &&
           std::abs(p.y()) < streets.tunnel_half_width;
}

}  // namespace

int DegradeOdometryInTunnel(const SimStreets& streets, double slip,
                            const std::vector<std::vector<Eigen::Isometry3d>>& T_world_sensor_truth,
                            std::vector<std::vector<Keyframe>>* robots) {
    int degraded = 0;
    for (size_t r = 0; r < robots->size(); ++r) {
        auto& kfs = (*robots)[r];
        const auto& truth = T_world_sensor_truth[r];
        Eigen::Isometry3d T_prev_old =
            kfs.empty() ? Eigen::Isometry3d::Identity() : kfs.front().T_odom_sensor;
        for (size_t i = 1; i < kfs.size(); ++i) {
            Eigen::Isometry3d step = T_prev_old.inverse() * kfs[i].T_odom_sensor;
            T_prev_old = kfs[i].T_odom_sensor;
            const Eigen::Vector3d mid = 0.5 * (truth[i - 1].translation() + truth[i].translation());
            if (InTunnel(streets, mid)) {
                step.translation() *= 1.0 - slip;
                ++degraded;
            }
            kfs[i].T_odom_sensor = kfs[i - 1].T_odom_sensor * step;
        }
    }
    return degraded;
}

}  // namespace certislam::slam
