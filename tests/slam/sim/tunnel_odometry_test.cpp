// DegradeOdometryInTunnel on a hand-built straight drive through a tunnel.
#include "slam/sim/tunnel_odometry.h"

#include <gtest/gtest.h>

namespace certislam::slam {
namespace {

constexpr double kTol = 1e-12;

SimStreets Tunnel() {
    SimStreets streets;
    streets.tunnel_x_begin = 10.0;
    streets.tunnel_x_end = 20.0;
    streets.tunnel_half_width = 5.0;
    return streets;
}

/// Keyframes every 5 m along x at height y, odometry equal to the truth.
void Drive(double y, std::vector<Keyframe>* kfs, std::vector<Eigen::Isometry3d>* truth) {
    for (int i = 0; i <= 6; ++i) {
        Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
        T.translation() = Eigen::Vector3d(5.0 * i, y, 0.0);
        truth->push_back(T);
        Keyframe kf;
        kf.index = i;
        kf.T_odom_sensor = T;
        kfs->push_back(kf);
    }
}

TEST(TunnelOdometry, ShortensOnlyStepsWhoseMidpointIsInsideTheTunnel) {
    std::vector<std::vector<Keyframe>> robots(2);
    std::vector<std::vector<Eigen::Isometry3d>> truth(2);
    Drive(0.0, &robots[0], &truth[0]);   // through the tunnel: midpoints 12.5 and 17.5 inside
    Drive(10.0, &robots[1], &truth[1]);  // beside it, outside the half width
    const double slip = 0.1;
    EXPECT_EQ(DegradeOdometryInTunnel(Tunnel(), slip, truth, &robots), 2);
    const std::vector<double> expected_x = {
        0, 5, 10, 15 - 5 * slip, 20 - 10 * slip, 25 - 10 * slip, 30 - 10 * slip};
    for (size_t i = 0; i < expected_x.size(); ++i) {
        EXPECT_NEAR(robots[0][i].T_odom_sensor.translation().x(), expected_x[i], kTol) << i;
        EXPECT_NEAR(robots[1][i].T_odom_sensor.translation().x(), 5.0 * i, kTol) << i;
        EXPECT_NEAR(robots[1][i].T_odom_sensor.translation().y(), 10.0, kTol) << i;
    }
}

TEST(TunnelOdometry, ZeroSlipCountsStepsButKeepsOdometry) {
    std::vector<std::vector<Keyframe>> robots(1);
    std::vector<std::vector<Eigen::Isometry3d>> truth(1);
    Drive(0.0, &robots[0], &truth[0]);
    EXPECT_EQ(DegradeOdometryInTunnel(Tunnel(), 0.0, truth, &robots), 2);
    for (size_t i = 0; i < robots[0].size(); ++i) {
        EXPECT_TRUE(robots[0][i].T_odom_sensor.isApprox(truth[0][i], kTol)) << i;
    }
}

}  // namespace
}  // namespace certislam::slam
