// Two robots on overlapping 25 m circles built by hand: drifting odometry, robot 1 in an unknown
// frame, noisy inter-robot loops at truly coincident places (for PCM and the solver tests).
#pragma once

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "slam/core/loop_closure.h"

namespace certislam::slam::testing {

/// Odometry of two robots and the loops between them.
struct TwoRobotCircles {
    std::vector<std::vector<Eigen::Isometry3d>> odometry;  ///< [robot][keyframe]
    std::vector<LoopClosure> loops;                        ///< inter-robot, a on robot 0
};

inline Eigen::Isometry3d Pose(double yaw, double x, double y, double z) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    T.translation() = Eigen::Vector3d(x, y, z);
    return T;
}

/// `n` keyframes per robot on a 25 m circle (robot 1 starts a quarter turn later), odometry
/// with small per-step noise, and `loops` inter-robot loops weighted kappa, tau.
inline TwoRobotCircles MakeTwoRobotCircles(int n, int loops, unsigned seed, double kappa,
                                           double tau) {
    std::mt19937 rng(seed);
    std::normal_distribution<double> noise(0.0, 1.0);
    TwoRobotCircles p;
    const auto truth = [&](int robot, int i) {
        const double a = 2.0 * M_PI * (i + robot * n / 4.0) / n;
        return Pose(a + M_PI / 2, 25.0 * std::cos(a), 25.0 * std::sin(a), 0.1 * robot);
    };
    const auto perturb = [&](const Eigen::Isometry3d& T, double st, double sr) {
        Eigen::Isometry3d out = T;
        out.translation() += st * Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
        out.linear() =
            out.linear() *
            Eigen::AngleAxisd(sr * noise(rng), Eigen::Vector3d::UnitZ()).toRotationMatrix() *
            Eigen::AngleAxisd(sr * noise(rng), Eigen::Vector3d::UnitX()).toRotationMatrix();
        return out;
    };
    const Eigen::Isometry3d T_world_odom1 = Pose(1.3, -40.0, 12.0, 3.0);
    for (int r = 0; r < 2; ++r) {
        std::vector<Eigen::Isometry3d> odom{r == 0 ? truth(0, 0)
                                                   : T_world_odom1.inverse() * truth(1, 0)};
        for (int i = 1; i < n; ++i) {
            const Eigen::Isometry3d step = truth(r, i - 1).inverse() * truth(r, i);
            odom.push_back(odom.back() * perturb(step, 0.03, 0.002));
        }
        p.odometry.push_back(odom);
    }
    for (int k = 0; k < loops; ++k) {
        LoopClosure l;
        const int j = (k * n / std::max(1, loops) + 3) % (n - n / 4);
        l.a = {0, j + n / 4};
        l.b = {1, j};
        l.T_a_b = perturb(truth(0, j + n / 4).inverse() * truth(1, j), 0.02, 0.001);
        l.kappa = kappa;
        l.tau = tau;
        p.loops.push_back(l);
    }
    return p;
}

}  // namespace certislam::slam::testing
