// The keyframe sources of `certislam run` and `certislam robot`: the mission simulator, SC-LIO-SAM
// keyframe folders, KITTI sequences, one folder split into robots with a rigid offset, ROS bags;
// each robot's keyframes on demand plus whatever ground truth the source has.
#pragma once

#include <Eigen/Geometry>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "actors/ingest_actor.h"
#include "slam/core/graph_split.h"
#include "slam/core/keyframe.h"
#include "slam/core/trajectory.h"
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

/// Each robot's keyframes, and the ground truth where the source has it.
class TeamSource {
  public:
    /// Reads (or plans) the data of every robot. Throws std::runtime_error with the reader's
    /// "FILE[:LINE]: what was wrong" when a file is bad.
    TeamSource(const SourceConfig& config, const std::vector<int>& robots);

    /// The source of one robot's keyframes (valid while this object lives).
    actors::KeyframeSource For(int robot) const;
    /// Keyframes robot `robot` will publish.
    int NumKeyframes(int robot) const;
    /// Odometry pose (T_odom_sensor) of keyframe `index` of `robot`.
    Eigen::Isometry3d Odometry(int robot, int index) const;
    /// Reference trajectory of `robot` (per keyframe, with its stamp), or nullopt.
    std::optional<slam::Trajectory> Truth(int robot) const;
    /// True when Truth() is in the team frame (robot 0's odometry frame) for every robot.
    bool TruthInTeamFrame() const { return truth_in_team_frame_; }
    /// What the reference is ("simulator ground truth", "KITTI ground truth", ...).
    const std::string& TruthKind() const { return truth_kind_; }
    /// True pose of robot `robot`'s odometry frame in the team frame, when the source knows it.
    std::optional<Eigen::Isometry3d> TrueTeamOdom(int robot) const;

  private:
    void Load(const SourceConfig& config, const std::vector<int>& robots);

    int max_keyframes_ = 0;
    std::shared_ptr<const slam::MissionGenerator> generator_;  ///< simulator
    std::map<int, std::vector<slam::Keyframe>> recorded_;      ///< files
    std::map<int, slam::Trajectory> truth_;                    ///< files with a reference
    std::map<int, Eigen::Isometry3d> T_team_odom_;             ///< known frames
    bool truth_in_team_frame_ = false;
    std::string truth_kind_;
};

}  // namespace certislam::bin
