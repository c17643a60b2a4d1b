// Test helpers for the TSDF tests: axis-aligned box scenes ray-cast by an ideal spinning LiDAR.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

#include "slam/core/keyframe.h"

namespace certislam::slam::testing {

/// An axis-aligned box, metres. A ground half-space is a box with a very low minimum z.
struct Box {
    Eigen::Vector3d min, max;
};

/// Distance from `p` to the surface of `b` (unsigned: inside counts too).
inline double DistanceToBoxSurface(const Box& b, const Eigen::Vector3d& p) {
    const Eigen::Vector3d q = (p - 0.5 * (b.min + b.max)).cwiseAbs() - 0.5 * (b.max - b.min);
    const double outside = q.cwiseMax(0.0).norm();
    const double inside = std::min(q.maxCoeff(), 0.0);
    return std::abs(outside + inside);
}

/// Entry distance of the ray o + t d (t > 0) into `b`, or +inf (slab method).
inline double RayBox(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const Box& b) {
    double t_near = 0.0, t_far = std::numeric_limits<double>::infinity();
    for (int a = 0; a < 3; ++a) {
        if (std::abs(d[a]) < 1e-12) {
            if (o[a] < b.min[a] || o[a] > b.max[a]) return t_far;
            continue;
        }
        double t0 = (b.min[a] - o[a]) / d[a], t1 = (b.max[a] - o[a]) / d[a];
        if (t0 > t1) std::swap(t0, t1);
        t_near = std::max(t_near, t0);
        t_far = std::min(t_far, t1);
        if (t_near > t_far) return std::numeric_limits<double>::infinity();
    }
    return t_near > 0.0 ? t_near : std::numeric_limits<double>::infinity();
}

/// A noiseless spinning LiDAR: `rings` beams from -25 to +5 degrees, `sectors` azimuths, hits
/// within `max_range` of the nearest box, returned in the sensor frame.
inline PointCloud ScanBoxes(const std::vector<Box>& scene, const Eigen::Isometry3d& T_world_sensor,
                            int rings = 32, int sectors = 720, double max_range = 40.0) {
    PointCloud cloud;
    const Eigen::Vector3d o = T_world_sensor.translation();
    const Eigen::Matrix3d R = T_world_sensor.rotation();
    for (int r = 0; r < rings; ++r) {
        const double el = (-25.0 + 30.0 * r / (rings - 1)) * std::numbers::pi / 180.0;
        for (int s = 0; s < sectors; ++s) {
            const double az = 2.0 * std::numbers::pi * s / sectors;
            const Eigen::Vector3d d_sensor(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az),
                                           std::sin(el));
            const Eigen::Vector3d d = R * d_sensor;
            double t = std::numeric_limits<double>::infinity();
            for (const Box& b : scene) t = std::min(t, RayBox(o, d, b));
            if (t <= max_range) cloud.push_back((t * d_sensor).cast<float>());
        }
    }
    return cloud;
}

/// A pose from translation and yaw (radians).
inline Eigen::Isometry3d Pose(double x, double y, double z, double yaw) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    T.translation() = Eigen::Vector3d(x, y, z);
    return T;
}

/// The ground (top at z = `height`) and one 2 m cube standing on it at (5, 1).
inline std::vector<Box> GroundAndCube(double height = -1.8) {
    return {Box{{-200, -200, -50}, {200, 200, height}}, Box{{4, 0, height}, {6, 2, height + 2.0}}};
}

}  // namespace certislam::slam::testing
