// The `source` part of a team configuration (simulator, keyframe folders, KITTI, a split folder,
// ROS bags, a pose graph): its settings, their checks, and a pose-graph source's graph per robot.
#pragma once

#include <Eigen/Geometry>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "slam/core/graph_split.h"
#include "slam/io/rosbag/rosbag_source_io.h"
#include "slam/sim/simulator.h"

namespace certislam::bin {

/// One KITTI odometry sequence (velodyne/*.bin under `folder`, poses file, calibration file).
struct KittiSequenceConfig {
    std::string folder;  ///< holds velodyne/ (and optionally times.txt)
    std::string poses;   ///< KITTI poses (T_world_cam0 per frame): odometry and ground truth
    std::string calib;   ///< calibration with a "Tr:" line
};

/// The `source` part of a team configuration.
struct SourceConfig {
    enum class Kind { kSimulator, kKeyframeFolder, kKitti, kSplit, kRosbag, kPoseGraph };
    Kind kind = Kind::kSimulator;     ///< which reader
    slam::SimulatorConfig simulator;  ///< kSimulator: the mission
    /// kSimulator: a named mission (slam::ScenarioNames(); "": the simulator's defaults).
    std::string scenario;
    int max_keyframes = 0;                     ///< per robot at most (0: all), >= 0
    std::map<int, std::string> paths;          ///< kKeyframeFolder / kRosbag: robot -> path
    std::map<int, KittiSequenceConfig> kitti;  ///< kKitti: robot -> sequence
    bool select_keyframes = true;              ///< kKitti: LIO-SAM's 1 m / 0.2 rad selection
    std::string split_path;                    ///< kSplit: the SC-LIO-SAM folder
    slam::RosbagSourceConfig rosbag;           ///< kRosbag: topics and pairing
    int split_robots = 0;                      ///< kSplit: robots the folder is split into
    Eigen::Vector3d offset_xyz_m = Eigen::Vector3d::Zero();    ///< kSplit: offset translation
    Eigen::Vector3d offset_rpy_deg = Eigen::Vector3d::Zero();  ///< kSplit: offset roll pitch yaw
    std::string graph_path;  ///< kPoseGraph: a g2o file (3D) or a dpgo CSV folder
    /// kPoseGraph, g2o file: robot -> vertices [begin, end) it owns; all zero: dpgo's split.
    std::map<int, std::pair<int, int>> ranges;
    Eigen::Isometry3d T_offset_world =
        Eigen::Isometry3d::Identity();  ///< kSplit: robot r > 0's
                                        ///< odometry frame is the world moved by this^r
};

/// `text` with every "{robot}" replaced by `robot` (per-robot topic names of one template).
std::string WithRobotId(std::string text, int robot);

/// Checks the `source` keys read from `config_path` against the team `robots` (one entry per
/// robot where the kind needs it) and derives the rest (T_offset_world, the simulator's team
/// size). Throws std::runtime_error naming "source.<field>" and the rule.
void FinishSourceConfig(const std::string& config_path, const std::vector<int>& robots,
                        SourceConfig* config);

/// kPoseGraph: the graph of `config.graph_path` split into the team's robots (by
/// `config.ranges` when given, else dpgo's contiguous split, or a CSV folder's own robots).
/// Throws std::runtime_error naming the file (and line) or "CONFIG: source.<key>" and the rule.
std::vector<slam::RobotGraph> LoadPoseGraphSource(const std::string& config_path,
                                                  const SourceConfig& config,
                                                  const std::vector<int>& robots);

}  // namespace certislam::bin
