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
#include "bin/config/source_config.h"
#include "slam/core/keyframe.h"
#include "slam/core/trajectory.h"
#include "slam/sim/simulator.h"

namespace certislam::bin {

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
