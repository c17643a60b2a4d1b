#include "slam/sim/simulator_trajectory.h"

#include <algorithm>
#include <cmath>

#include "slam/core/check.h"

namespace certislam::slam {
namespace {

constexpr double kSampleStepM = 0.5;
constexpr int kCornerSamples = 24;

Eigen::Vector2d RightNormal(const Eigen::Vector2d& u) { return {u.y(), -u.x()}; }

void AppendLine(std::vector<Eigen::Vector2d>* pts, const Eigen::Vector2d& to) {
    const Eigen::Vector2d from = pts->back();
    const int n = std::max(1, static_cast<int>(std::ceil((to - from).norm() / kSampleStepM)));
    for (int k = 1; k <= n; ++k) pts->push_back(from + (to - from) * (double(k) / n));
}

void AppendCorner(std::vector<Eigen::Vector2d>* pts, const Eigen::Vector2d& p1,
                  const Eigen::Vector2d& p2) {
    const Eigen::Vector2d p0 = pts->back();
    for (int k = 1; k <= kCornerSamples; ++k) {
        const double t = double(k) / kCornerSamples;
        pts->push_back((1 - t) * (1 - t) * p0 + 2 * (1 - t) * t * p1 + t * t * p2);
    }
}

}  // namespace

SimPath::SimPath(const std::vector<Eigen::Vector2d>& wp, double lane_offset_m,
                 double corner_cut_m) {
    CERTISLAM_CHECK(wp.size() >= 2);
    const size_t n = wp.size();
    std::vector<Eigen::Vector2d> dir(n - 1);
    for (size_t i = 0; i + 1 < n; ++i) {
        CERTISLAM_CHECK((wp[i + 1] - wp[i]).norm() > 1e-6);
        dir[i] = (wp[i + 1] - wp[i]).normalized();
    }
    // Lane polyline: miter-offset vertices.
    std::vector<Eigen::Vector2d> lane(n);
    lane[0] = wp[0] + lane_offset_m * RightNormal(dir[0]);
    lane[n - 1] = wp[n - 1] + lane_offset_m * RightNormal(dir[n - 2]);
    for (size_t i = 1; i + 1 < n; ++i) {
        const Eigen::Vector2d a = RightNormal(dir[i - 1]);
        const Eigen::Vector2d b = RightNormal(dir[i]);
        CERTISLAM_CHECK(1.0 + a.dot(b) > 1e-3);  // no U-turns
        lane[i] = wp[i] + lane_offset_m * (a + b) / (1.0 + a.dot(b));
    }
    points_.push_back(lane[0]);
    for (size_t i = 1; i + 1 < n; ++i) {
        const Eigen::Vector2d in = lane[i] - lane[i - 1];
        const Eigen::Vector2d out = lane[i + 1] - lane[i];
        const double c = std::min({corner_cut_m, 0.45 * in.norm(), 0.45 * out.norm()});
        AppendLine(&points_, lane[i] - in.normalized() * c);
        AppendCorner(&points_, lane[i], lane[i] + out.normalized() * c);
    }
    AppendLine(&points_, lane[n - 1]);
    // Arc length and unwrapped heading (mean of the adjacent segments' headings).
    const size_t m = points_.size();
    std::vector<double> seg_yaw(m - 1);
    s_.assign(m, 0.0);
    for (size_t i = 0; i + 1 < m; ++i) {
        const Eigen::Vector2d d = points_[i + 1] - points_[i];
        s_[i + 1] = s_[i] + d.norm();
        seg_yaw[i] = std::atan2(d.y(), d.x());
        if (i > 0) {
            seg_yaw[i] = seg_yaw[i - 1] + std::remainder(seg_yaw[i] - seg_yaw[i - 1], 2 * M_PI);
        }
    }
    yaw_.resize(m);
    yaw_[0] = seg_yaw[0];
    yaw_[m - 1] = seg_yaw[m - 2];
    for (size_t i = 1; i + 1 < m; ++i) yaw_[i] = 0.5 * (seg_yaw[i - 1] + seg_yaw[i]);
}

void SimPath::At(double s, Eigen::Vector2d* position, double* yaw) const {
    s = std::clamp(s, 0.0, length());
    size_t i = std::upper_bound(s_.begin(), s_.end(), s) - s_.begin();
    i = std::clamp<size_t>(i, 1, s_.size() - 1);
    const double len = s_[i] - s_[i - 1];
    const double a = len > 0.0 ? (s - s_[i - 1]) / len : 0.0;
    *position = (1 - a) * points_[i - 1] + a * points_[i];
    *yaw = (1 - a) * yaw_[i - 1] + a * yaw_[i];
}

Eigen::Isometry3d PathPose(const SimPath& path, double s, double mount_height_m) {
    Eigen::Vector2d p;
    double yaw = 0.0;
    path.At(s, &p, &yaw);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    T.translation() = Eigen::Vector3d(p.x(), p.y(), mount_height_m);
    return T;
}

SimRobotTrajectory IntegrateTrajectory(const SimPath& path, const SimulatorConfig& cfg,
                                       std::mt19937_64& rng) {
    const auto& d = cfg.drift;
    std::normal_distribution<double> normal(0.0, 1.0);
    double yaw_bias = d.yaw_rate_bias_sigma_rad_s * normal(rng);
    double vz_bias = d.vertical_velocity_bias_sigma_m_s * normal(rng);
    const double scale = 1.0 + d.scale_error_sigma * normal(rng);

    SimRobotTrajectory out;
    const int keyframes = static_cast<int>(std::floor(path.length() / cfg.keyframe_spacing_m)) + 1;
    const int substeps =
        std::max(1, static_cast<int>(
                        std::ceil(cfg.keyframe_spacing_m / (cfg.speed_m_s * cfg.odometry_step_s))));
    const double ds = cfg.keyframe_spacing_m / substeps;
    const double dt = ds / cfg.speed_m_s;
    const double sqrt_dt = std::sqrt(dt);
    Eigen::Vector3d p_odom = Eigen::Vector3d::Zero();  // position in the odometry frame
    double yaw_odom = 0.0;
    for (int k = 0; k < keyframes; ++k) {
        const double s = k * cfg.keyframe_spacing_m;
        out.s.push_back(s);
        out.truth.push_back(PathPose(path, s, cfg.lidar.mount_height_m));
        Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
        T.linear() = Eigen::AngleAxisd(yaw_odom, Eigen::Vector3d::UnitZ()).toRotationMatrix();
        T.translation() = p_odom;
        out.odometry.push_back(T);
        if (k + 1 == keyframes) break;
        for (int j = 0; j < substeps; ++j) {
            Eigen::Vector2d p0, p1;
            double y0 = 0.0, y1 = 0.0;
            path.At(s + j * ds, &p0, &y0);
            path.At(s + (j + 1) * ds, &p1, &y1);
            // True body-frame motion of this step, then the odometry's version of it.
            const Eigen::Vector2d body = Eigen::Rotation2Dd(-y0) * (p1 - p0);
            const Eigen::Vector2d body_meas =
                scale * body +
                d.velocity_noise_m_s * dt * Eigen::Vector2d(normal(rng), normal(rng));
            const double dyaw = (y1 - y0) + (yaw_bias + d.yaw_rate_noise_rad_s * normal(rng)) * dt;
            const Eigen::Vector2d step = Eigen::Rotation2Dd(yaw_odom) * body_meas;
            p_odom += Eigen::Vector3d(step.x(), step.y(),
                                      (vz_bias + d.velocity_noise_m_s * normal(rng)) * dt);
            yaw_odom += dyaw;
            yaw_bias += d.yaw_rate_bias_walk_rad_s_sqrt_s * sqrt_dt * normal(rng);
            vz_bias += d.vertical_velocity_bias_walk_m_s_sqrt_s * sqrt_dt * normal(rng);
        }
    }
    return out;
}

}  // namespace certislam::slam
