// Small pose graphs with known optima or known suboptimal critical points, for certify tests.
#pragma once

#include <Eigen/Dense>
#include <cmath>
#include <numbers>
#include <random>

#include "slam/core/pose_graph.h"

namespace certislam::certify::testing {

/// Rotation by angle about z (3D) or in the plane (2D).
inline Eigen::MatrixXd Rot(int d, double angle) {
    Eigen::MatrixXd R = Eigen::MatrixXd::Identity(d, d);
    R(0, 0) = std::cos(angle);
    R(0, 1) = -std::sin(angle);
    R(1, 0) = std::sin(angle);
    R(1, 1) = std::cos(angle);
    return R;
}

inline slam::RelativePoseMeasurement Edge(int i, int j, const Eigen::MatrixXd& R,
                                          const Eigen::VectorXd& t, double kappa, double tau) {
    slam::RelativePoseMeasurement e;
    e.i = i;
    e.j = j;
    e.R = R;
    e.t = t;
    e.kappa = kappa;
    e.tau = tau;
    return e;
}

/// A cycle of n poses whose every measurement is the identity (R~ = I, t~ = 0): f* = 0, and the
/// "twisted" poses R_k = Rot(2 pi k / n), t_k = 0 are a critical point with f > 0 (each R_k is
/// the mean direction of its two neighbours), a textbook suboptimal stationary point.
inline slam::PoseGraph IdentityCycle(int d, int n) {
    slam::PoseGraph graph;
    graph.d = d;
    graph.n = n;
    for (int k = 0; k < n; ++k) {
        graph.edges.push_back(Edge(k, (k + 1) % n, Eigen::MatrixXd::Identity(d, d),
                                   Eigen::VectorXd::Zero(d), 1.0, 1.0));
    }
    return graph;
}

/// The twisted critical point of IdentityCycle as X (d x (d+1)n).
inline Eigen::MatrixXd TwistedCycle(int d, int n) {
    Eigen::MatrixXd X = Eigen::MatrixXd::Zero(d, (d + 1) * n);
    for (int k = 0; k < n; ++k) {
        X.block(0, slam::BlockColumn(k, d), d, d) = Rot(d, 2.0 * std::numbers::pi * k / n);
    }
    return X;
}

/// Random rotation of angle about a random axis (d = 2: in the plane).
inline Eigen::MatrixXd RandomRotation(int d, double angle, std::mt19937& rng) {
    std::normal_distribution<double> normal;
    if (d == 2) return Rot(2, angle);
    const Eigen::Vector3d axis(normal(rng), normal(rng), normal(rng));
    return Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
}

/// A synthetic 3D "sphere" like sphere2500: `rings` rings of `per_ring` poses on a sphere of
/// radius 10 m, odometry along the path and loop closures to the pose one ring up. Measurements
/// are the truth perturbed by rotations of angle N(0, sigma_rad) and translations N(0, sigma_m);
/// kappa = 1 / (2 sigma_rad^2), tau = 1 / sigma_m^2. `truth` receives the true poses.
inline slam::PoseGraph NoisySphere(int rings, int per_ring, double sigma_rad, double sigma_m,
                                   unsigned seed, Eigen::MatrixXd* truth) {
    std::mt19937 rng(seed);
    std::normal_distribution<double> normal;
    const int n = rings * per_ring;
    slam::PoseGraph graph;
    graph.d = 3;
    graph.n = n;
    *truth = Eigen::MatrixXd::Zero(3, 4 * n);
    for (int k = 0; k < n; ++k) {
        const double polar = std::numbers::pi * (k / per_ring + 1) / (rings + 1);
        const double azimuth = 2.0 * std::numbers::pi * (k % per_ring) / per_ring;
        const Eigen::Matrix3d R = (Eigen::AngleAxisd(azimuth, Eigen::Vector3d::UnitZ()) *
                                   Eigen::AngleAxisd(polar, Eigen::Vector3d::UnitY()))
                                      .toRotationMatrix();
        truth->block(0, 4 * k, 3, 3) = R;
        truth->col(4 * k + 3) = 10.0 * R.col(2);
    }
    auto add = [&](int i, int j) {
        const Eigen::Matrix3d Ri = truth->block(0, 4 * i, 3, 3), Rj = truth->block(0, 4 * j, 3, 3);
        const Eigen::Vector3d ti = truth->col(4 * i + 3), tj = truth->col(4 * j + 3);
        Eigen::MatrixXd R = Ri.transpose() * Rj * RandomRotation(3, sigma_rad * normal(rng), rng);
        Eigen::Vector3d t = Ri.transpose() * (tj - ti);
        for (int a = 0; a < 3; ++a) t[a] += sigma_m * normal(rng);
        graph.edges.push_back(
            Edge(i, j, R, t, 1.0 / (2.0 * sigma_rad * sigma_rad), 1.0 / (sigma_m * sigma_m)));
    };
    for (int k = 0; k + 1 < n; ++k) add(k, k + 1);
    for (int k = 0; k + per_ring < n; ++k) add(k, k + per_ring);
    return graph;
}

/// Poses with every rotation drawn at random (a bad initial guess) and translations zero.
inline Eigen::MatrixXd RandomPoses(int d, int n, unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> angle(-std::numbers::pi, std::numbers::pi);
    Eigen::MatrixXd P = Eigen::MatrixXd::Zero(d, (d + 1) * n);
    for (int k = 0; k < n; ++k) P.block(0, (d + 1) * k, d, d) = RandomRotation(d, angle(rng), rng);
    return P;
}

}  // namespace certislam::certify::testing
