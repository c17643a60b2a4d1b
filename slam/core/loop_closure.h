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

}  // namespace certislam::slam
