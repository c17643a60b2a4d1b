// Small pose graphs with known optima or known suboptimal critical points, for certify tests.
#pragma once

#include <Eigen/Dense>
#include <cmath>
#include <numbers>

#include "slam/pose_graph.h"

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

}  // namespace certislam::certify::testing
