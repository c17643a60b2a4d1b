// The weights of a joint graph's edges from standard deviations: shared by the pipeline and the
// solvers of the actor graph (kept apart from mission.h, which needs the front end).
#pragma once

namespace certislam::certify {

/// Weights of the edges of the joint graph, from standard deviations (MATH.md's rules for an
/// isotropic information matrix: tau = 1 / sigma_t^2, kappa = 1 / (2 sigma_r^2)).
struct EdgeNoiseConfig {
    double odometry_sigma_t_m = 0.05;     ///< odometry translation std per keyframe step, > 0
    double odometry_sigma_r_rad = 0.002;  ///< odometry rotation std per keyframe step, > 0
    double loop_sigma_t_m = 0.05;         ///< loop-closure translation std, > 0
    double loop_sigma_r_rad = 0.002;      ///< loop-closure rotation std, > 0

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

}  // namespace certislam::certify
