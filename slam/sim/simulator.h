// The LiDAR mission simulator: robots driving overlapping routes through a generated city,
// a ray-cast spinning LiDAR, drifting LiDAR-inertial-like odometry, and exact ground truth.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "slam/core/keyframe.h"
#include "slam/sim/sim_city.h"
#include "slam/sim/sim_routes.h"
#include "slam/sim/sim_world.h"

namespace certislam::slam {

/// A spinning multi-beam LiDAR: rings evenly spread over the vertical field of view.
struct SimLidarConfig {
    int rings = 32;                          ///< beams, >= 1 (32 default; 64 for an OS1-64)
    double vertical_fov_min_deg = -25.0;     ///< lowest beam elevation, > -90
    double vertical_fov_max_deg = 15.0;      ///< highest beam elevation, >= min, < 90
    double horizontal_resolution_deg = 0.4;  ///< azimuth step, in (0, 360]
    double min_range_m = 1.0;                ///< closer returns are dropped, >= 0
    double max_range_m = 90.0;               ///< farther surfaces give no return, > min_range_m
    double range_noise_sigma_m = 0.02;       ///< Gaussian range noise (std), >= 0
    double mount_height_m = 1.8;             ///< sensor height above the ground, > 0

    /// An Ouster OS1-64-like sensor: 64 rings over +-22.5 degrees.
    static SimLidarConfig Ouster64();
    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// Odometry drift like LiDAR-inertial odometry: random-walk biases on yaw rate and vertical
/// velocity and a constant scale error, integrated along the path (not per-keyframe noise).
struct SimOdometryDriftConfig {
    double yaw_rate_bias_sigma_rad_s = 2.5e-4;       ///< std of the initial yaw-rate bias, >= 0
    double yaw_rate_bias_walk_rad_s_sqrt_s = 3e-5;   ///< bias random walk, >= 0
    double vertical_velocity_bias_sigma_m_s = 4e-3;  ///< std of the initial z-velocity bias, >= 0
    double vertical_velocity_bias_walk_m_s_sqrt_s = 5e-4;  ///< bias random walk, >= 0
    double scale_error_sigma = 5e-3;     ///< std of the constant distance scale error, >= 0
    double velocity_noise_m_s = 0.02;    ///< white noise on the velocity per step, >= 0
    double yaw_rate_noise_rad_s = 2e-3;  ///< white noise on the yaw rate per step, >= 0

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// Everything a simulated mission depends on; the seed fixes world, noise and drift.
struct SimulatorConfig {
    std::uint64_t seed = 1;                ///< one seed for world, drift and range noise
    int num_robots = 2;                    ///< robots, >= 1 (0 and 1 have hand-made routes)
    SimWorldConfig world;                  ///< the city
    SimLidarConfig lidar;                  ///< the sensor
    SimOdometryDriftConfig drift;          ///< the odometry error model
    double speed_m_s = 5.0;                ///< driving speed, > 0
    double keyframe_spacing_m = 3.0;       ///< travelled distance between keyframes, > 0
    double odometry_step_s = 0.1;          ///< odometry integration step, > 0
    double lane_offset_m = 2.0;            ///< robots drive this far right of the centreline, >= 0
    double corner_cut_m = 8.0;             ///< corners are rounded from this far before them, > 0
    double random_route_length_m = 500.0;  ///< route length of robots >= 2 (random walks), > 0
    double robot_start_interval_s = 0.0;   ///< robot r's stamps start at r * this, >= 0
    /// Fraction of the along-track motion odometry misses inside the tunnel, [0, 1): LiDAR
    /// odometry in a featureless tunnel under-observes its axis (0: no degradation).
    double tunnel_slip = 0.0;
    /// Optional routes (world x-y waypoints on street centrelines, no U-turns) overriding the
    /// default ones; robot r uses routes[r] when r < routes.size().
    std::vector<std::vector<Eigen::Vector2d>> routes;

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// One simulated keyframe and where it really was.
struct SimulatedKeyframe {
    Keyframe keyframe;                       ///< odometry pose, stamp and cloud (sensor frame)
    Eigen::Isometry3d T_world_sensor_truth;  ///< exact pose in the world
};

/// A whole mission: per robot, its keyframes and the exact ground truth.
struct SimulatedMission {
    std::vector<std::vector<Keyframe>> robots;                         ///< [robot][keyframe]
    std::vector<std::vector<Eigen::Isometry3d>> T_world_sensor_truth;  ///< [robot][keyframe]
    std::vector<Eigen::Isometry3d> T_world_odom;  ///< each robot's odometry frame in the world
};

/// Generates a mission lazily: construction plans routes and integrates the odometry (cheap);
/// Generate() ray-casts one keyframe's cloud. Results do not depend on the call order.
class MissionGenerator {
  public:
    /// Validates `config` (throws std::invalid_argument) and builds world and trajectories.
    explicit MissionGenerator(const SimulatorConfig& config);

    int num_robots() const { return static_cast<int>(truth_.size()); }  ///< robots
    /// Keyframes of `robot`.
    int num_keyframes(int robot) const { return static_cast<int>(truth_.at(robot).size()); }
    /// Keyframe `index` of `robot` with its cloud (ray cast on every call).
    SimulatedKeyframe Generate(int robot, int index) const;
    /// Keyframe without its cloud (pose and stamp only).
    Keyframe PoseOnly(int robot, int index) const;
    /// Exact pose of keyframe `index` of `robot` in the world.
    const Eigen::Isometry3d& T_world_sensor_truth(int robot, int index) const {
        return truth_.at(robot).at(index);
    }
    /// The robot's odometry frame in the world (its first true pose: odometry starts at I).
    const Eigen::Isometry3d& T_world_odom(int robot) const { return truth_.at(robot).front(); }
    /// Ray-casts one scan from `T_world_sensor`; `noise_seed` fixes its range noise.
    PointCloud Scan(const Eigen::Isometry3d& T_world_sensor, std::uint64_t noise_seed) const;

    const SimWorld& world() const { return world_.world; }        ///< the geometry
    const SimStreets& streets() const { return world_.streets; }  ///< the street layout
    const SimulatorConfig& config() const { return config_; }     ///< the configuration

  private:
    SimulatorConfig config_;
    GeneratedWorld world_;
    std::vector<Eigen::Vector3d> ray_dirs_;              // sensor frame, unit
    std::vector<std::vector<Eigen::Isometry3d>> truth_;  // [robot][keyframe]
    std::vector<std::vector<Eigen::Isometry3d>> odom_;   // [robot][keyframe]
    std::vector<std::vector<std::int64_t>> stamps_ns_;   // [robot][keyframe]
};

/// Generates every keyframe of every robot (a few seconds for a few hundred keyframes).
SimulatedMission SimulateMission(const SimulatorConfig& config);

}  // namespace certislam::slam
