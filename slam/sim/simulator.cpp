#include "slam/sim/simulator.h"

#include <cmath>
#include <random>
#include <stdexcept>
#include <string>

#include "slam/sim/simulator_trajectory.h"
#include "slam/sim/tunnel_odometry.h"

namespace certislam::slam {
namespace {

void Require(bool ok, const char* type, const char* field, double value, const char* rule) {
    if (!ok) {
        throw std::invalid_argument(std::string(type) + "." + field + " = " +
                                    std::to_string(value) + ": must be " + rule);
    }
}

// SplitMix64 finaliser: decorrelated per-robot / per-keyframe seeds from one mission seed.
std::uint64_t Mix(std::uint64_t x) {
    x += 0x9e3779b97f4a7c15ULL;
    x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
    x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
    return x ^ (x >> 31);
}

std::uint64_t SubSeed(std::uint64_t seed, std::uint64_t a, std::uint64_t b) {
    return Mix(Mix(Mix(seed) ^ a) ^ b);
}

constexpr std::uint64_t kDriftStream = 1;
constexpr std::uint64_t kNoiseStream = 2;
constexpr std::uint64_t kRouteStream = 3;

}  // namespace

SimLidarConfig SimLidarConfig::Ouster64() {
    SimLidarConfig c;
    c.rings = 64;
    c.vertical_fov_min_deg = -22.5;
    c.vertical_fov_max_deg = 22.5;
    c.horizontal_resolution_deg = 0.7;
    return c;
}

void SimLidarConfig::Validate() const {
    const char* t = "SimLidarConfig";
    Require(rings >= 1, t, "rings", rings, ">= 1");
    Require(vertical_fov_min_deg > -90.0, t, "vertical_fov_min_deg", vertical_fov_min_deg, "> -90");
    Require(vertical_fov_max_deg >= vertical_fov_min_deg && vertical_fov_max_deg < 90.0, t,
            "vertical_fov_max_deg", vertical_fov_max_deg, ">= vertical_fov_min_deg and < 90");
    Require(horizontal_resolution_deg > 0.0 && horizontal_resolution_deg <= 360.0, t,
            "horizontal_resolution_deg", horizontal_resolution_deg, "in (0, 360]");
    Require(min_range_m >= 0.0, t, "min_range_m", min_range_m, ">= 0");
    Require(max_range_m > min_range_m, t, "max_range_m", max_range_m, "> min_range_m");
    Require(range_noise_sigma_m >= 0.0, t, "range_noise_sigma_m", range_noise_sigma_m, ">= 0");
    Require(mount_height_m > 0.0, t, "mount_height_m", mount_height_m, "> 0");
}

void SimOdometryDriftConfig::Validate() const {
    const char* t = "SimOdometryDriftConfig";
    Require(yaw_rate_bias_sigma_rad_s >= 0.0, t, "yaw_rate_bias_sigma_rad_s",
            yaw_rate_bias_sigma_rad_s, ">= 0");
    Require(yaw_rate_bias_walk_rad_s_sqrt_s >= 0.0, t, "yaw_rate_bias_walk_rad_s_sqrt_s",
            yaw_rate_bias_walk_rad_s_sqrt_s, ">= 0");
    Require(vertical_velocity_bias_sigma_m_s >= 0.0, t, "vertical_velocity_bias_sigma_m_s",
            vertical_velocity_bias_sigma_m_s, ">= 0");
    Require(vertical_velocity_bias_walk_m_s_sqrt_s >= 0.0, t,
            "vertical_velocity_bias_walk_m_s_sqrt_s", vertical_velocity_bias_walk_m_s_sqrt_s,
            ">= 0");
    Require(scale_error_sigma >= 0.0, t, "scale_error_sigma", scale_error_sigma, ">= 0");
    Require(velocity_noise_m_s >= 0.0, t, "velocity_noise_m_s", velocity_noise_m_s, ">= 0");
    Require(yaw_rate_noise_rad_s >= 0.0, t, "yaw_rate_noise_rad_s", yaw_rate_noise_rad_s, ">= 0");
}

void SimulatorConfig::Validate() const {
    const char* t = "SimulatorConfig";
    Require(num_robots >= 1, t, "num_robots", num_robots, ">= 1");
    world.Validate();
    lidar.Validate();
    drift.Validate();
    Require(speed_m_s > 0.0, t, "speed_m_s", speed_m_s, "> 0");
    Require(keyframe_spacing_m > 0.0, t, "keyframe_spacing_m", keyframe_spacing_m, "> 0");
    Require(odometry_step_s > 0.0, t, "odometry_step_s", odometry_step_s, "> 0");
    Require(lane_offset_m >= 0.0 && lane_offset_m < world.street_half_width_m, t, "lane_offset_m",
            lane_offset_m, ">= 0 and < world.street_half_width_m");
    Require(corner_cut_m > 0.0, t, "corner_cut_m", corner_cut_m, "> 0");
    Require(random_route_length_m > 0.0, t, "random_route_length_m", random_route_length_m, "> 0");
    Require(robot_start_interval_s >= 0.0, t, "robot_start_interval_s", robot_start_interval_s,
            ">= 0");
    Require(tunnel_slip >= 0.0 && tunnel_slip < 1.0, t, "tunnel_slip", tunnel_slip, "in [0, 1)");
    for (size_t r = 0; r < routes.size(); ++r) {
        Require(routes[r].size() >= 2, t, "routes[r].size()", double(routes[r].size()), ">= 2");
    }
}

MissionGenerator::MissionGenerator(const SimulatorConfig& config)
    : config_((config.Validate(), config)), world_(GenerateWorld(config.world, config.seed)) {
    const auto& l = config_.lidar;
    const int columns = static_cast<int>(std::round(360.0 / l.horizontal_resolution_deg));
    ray_dirs_.reserve(static_cast<size_t>(columns) * l.rings);
    for (int c = 0; c < columns; ++c) {
        const double az = 2.0 * M_PI * c / columns;
        for (int r = 0; r < l.rings; ++r) {
            const double el_deg =
                l.rings == 1
                    ? l.vertical_fov_min_deg
                    : l.vertical_fov_min_deg +
                          (l.vertical_fov_max_deg - l.vertical_fov_min_deg) * r / (l.rings - 1);
            const double el = el_deg * M_PI / 180.0;
            ray_dirs_.emplace_back(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az),
                                   std::sin(el));
        }
    }
    for (int r = 0; r < config_.num_robots; ++r) {
        const auto route =
            r < static_cast<int>(config_.routes.size())
                ? config_.routes[r]
                : DefaultRoute(world_.streets, r, SubSeed(config_.seed, kRouteStream, r),
                               config_.random_route_length_m);
        const SimPath path(route, config_.lane_offset_m, config_.corner_cut_m);
        std::mt19937_64 rng(SubSeed(config_.seed, kDriftStream, r));
        SimRobotTrajectory traj = IntegrateTrajectory(path, config_, rng);
        if (config_.tunnel_slip > 0.0) {
            DegradeOdometryInTunnel(world_.streets, config_.tunnel_slip, traj.truth,
                                    &traj.odometry);
        }
        std::vector<std::int64_t> stamps;
        for (double s : traj.s) {
            const double t = r * config_.robot_start_interval_s + s / config_.speed_m_s;
            stamps.push_back(static_cast<std::int64_t>(std::llround(t * 1e9)));
        }
        truth_.push_back(std::move(traj.truth));
        odom_.push_back(std::move(traj.odometry));
        stamps_ns_.push_back(std::move(stamps));
    }
}

PointCloud MissionGenerator::Scan(const Eigen::Isometry3d& T_world_sensor,
                                  std::uint64_t noise_seed) const {
    const auto& l = config_.lidar;
    std::mt19937_64 rng(noise_seed);
    std::normal_distribution<double> noise(0.0, l.range_noise_sigma_m);
    const Eigen::Matrix3d R = T_world_sensor.linear();
    const Eigen::Vector3d o = T_world_sensor.translation();
    PointCloud cloud;
    cloud.reserve(ray_dirs_.size());
    for (const Eigen::Vector3d& d : ray_dirs_) {
        const auto hit = world_.world.CastRay(o, R * d, l.min_range_m, l.max_range_m);
        if (!hit) continue;
        const double range = hit->t + (l.range_noise_sigma_m > 0.0 ? noise(rng) : 0.0);
        cloud.push_back((d * range).cast<float>());
    }
    return cloud;
}

Keyframe MissionGenerator::PoseOnly(int robot, int index) const {
    Keyframe kf;
    kf.robot = robot;
    kf.index = index;
    kf.stamp_ns = stamps_ns_.at(robot).at(index);
    kf.T_odom_sensor = odom_.at(robot).at(index);
    return kf;
}

SimulatedKeyframe MissionGenerator::Generate(int robot, int index) const {
    SimulatedKeyframe out{PoseOnly(robot, index), T_world_sensor_truth(robot, index)};
    const std::uint64_t seed =
        SubSeed(config_.seed, kNoiseStream, (std::uint64_t(robot) << 32) | index);
    out.keyframe.cloud = std::make_shared<const PointCloud>(Scan(out.T_world_sensor_truth, seed));
    return out;
}

SimulatedMission SimulateMission(const SimulatorConfig& config) {
    const MissionGenerator gen(config);
    SimulatedMission m;
    for (int r = 0; r < gen.num_robots(); ++r) {
        m.robots.emplace_back();
        m.T_world_sensor_truth.emplace_back();
        m.T_world_odom.push_back(gen.T_world_odom(r));
        for (int k = 0; k < gen.num_keyframes(r); ++k) {
            SimulatedKeyframe kf = gen.Generate(r, k);
            m.robots.back().push_back(std::move(kf.keyframe));
            m.T_world_sensor_truth.back().push_back(kf.T_world_sensor_truth);
        }
    }
    return m;
}

}  // namespace certislam::slam
