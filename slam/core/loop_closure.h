// A verified loop closure between two keyframes (same robot or two robots), as the mission
// pipeline, the baselines and the actors exchange it.
#pragma once

#include <Eigen/Geometry>

#include "slam/core/pose_graph.h"

namespace certislam::slam {

/// A relative-pose constraint T_a_b between keyframe `a` and keyframe `b` (sensor frames).
struct LoopClosure {
    PoseId a;                                                 ///< tail keyframe
    PoseId b;                                                 ///< head keyframe
    Eigen::Isometry3d T_a_b = Eigen::Isometry3d::Identity();  ///< pose of b in a's frame
    double kappa = 1.0;                                       ///< rotation weight (MATH.md), > 0
    double tau = 1.0;                                         ///< translation weight, > 0
    double sc_distance = 1.0;        ///< Scan Context distance that proposed it, [0, 1]
    double fitness = 0.0;            ///< registration fitness (mean squared residual, m^2)
    bool from_ground_truth = false;  ///< true only in the loud ground-truth fallback

    /// True when the two keyframes belong to different robots.
    bool inter_robot() const { return a.robot != b.robot; }
};

/// The one conversion of a relative pose T_i_j (3D) into the measurement of edge i -> j, with
/// weights kappa and tau (MATH.md objective).
inline RelativePoseMeasurement MeasurementOf(int i, int j, const Eigen::Isometry3d& T_i_j,
                                             double kappa, double tau) {
    RelativePoseMeasurement m;
    m.i = i;
    m.j = j;
    m.R = T_i_j.linear();
    m.t = T_i_j.translation();
    m.kappa = kappa;
    m.tau = tau;
    return m;
}

/// A loop closure as the measurement of edge i -> j (i, j: the global indices of a and b).
inline RelativePoseMeasurement MeasurementOf(const LoopClosure& loop, int i, int j) {
    return MeasurementOf(i, j, loop.T_a_b, loop.kappa, loop.tau);
}

/// Weights of an isotropic information matrix from standard deviations (MATH.md's 3D rules):
/// tau = 1 / sigma_t^2, kappa = 1 / (2 sigma_r^2).
inline double TranslationWeight(double sigma_t) { return 1.0 / (sigma_t * sigma_t); }
inline double RotationWeight(double sigma_r) { return 1.0 / (2.0 * sigma_r * sigma_r); }

}  // namespace certislam::slam
