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
                            const std::vector<Eigen::Isometry3d>& T_world_sensor_truth,
                            std::vector<Eigen::Isometry3d>* T_odom_sensor) {
    auto& odom = *T_odom_sensor;
    int degraded = 0;
    Eigen::Isometry3d T_prev_old = odom.empty() ? Eigen::Isometry3d::Identity() : odom.front();
    for (size_t i = 1; i < odom.size(); ++i) {
        Eigen::Isometry3d step = T_prev_old.inverse() * odom[i];
        T_prev_old = odom[i];
        const Eigen::Vector3d mid = 0.5 * (T_world_sensor_truth[i - 1].translation() +
                                           T_world_sensor_truth[i].translation());
        if (InTunnel(streets, mid)) {
            step.translation() *= 1.0 - slip;
            ++degraded;
        }
        odom[i] = odom[i - 1] * step;
    }
    return degraded;
}

int DegradeOdometryInTunnel(const SimStreets& streets, double slip,
                            const std::vector<std::vector<Eigen::Isometry3d>>& T_world_sensor_truth,
                            std::vector<std::vector<Keyframe>>* robots) {
    int degraded = 0;
    for (size_t r = 0; r < robots->size(); ++r) {
        auto& kfs = (*robots)[r];
        std::vector<Eigen::Isometry3d> odom;
        for (const auto& kf : kfs) odom.push_back(kf.T_odom_sensor);
        degraded += DegradeOdometryInTunnel(streets, slip, T_world_sensor_truth[r], &odom);
        for (size_t i = 0; i < kfs.size(); ++i) kfs[i].T_odom_sensor = odom[i];
    }
    return degraded;
}

}  // namespace certislam::slam
