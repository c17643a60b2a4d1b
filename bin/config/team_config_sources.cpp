// Team keyframe sources: the readers behind the `source` configuration, and ground truth.
#include "bin/config/team_config_sources.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <stdexcept>

#include "slam/io/keyframe_sources_io.h"
#include "slam/io/rosbag/rosbag_source_io.h"

namespace certislam::bin {

TeamSource::TeamSource(const SourceConfig& config, const std::vector<int>& robots)
    : max_keyframes_(config.max_keyframes) {
    if (config.kind != SourceConfig::Kind::kSimulator) {
        Load(config, robots);
        return;
    }
    generator_ = std::make_shared<slam::MissionGenerator>(config.simulator);
    const Eigen::Isometry3d T_team_world = generator_->T_world_odom(0).inverse();
    for (const int r : robots) {
        slam::Trajectory truth;
        for (int i = 0; i < NumKeyframes(r); ++i) {
            truth.push_back({static_cast<double>(generator_->PoseOnly(r, i).stamp_ns) * 1e-9,
                             T_team_world * generator_->T_world_sensor_truth(r, i)});
        }
        truth_[r] = std::move(truth);
        T_team_odom_[r] = T_team_world * generator_->T_world_odom(r);
    }
    truth_in_team_frame_ = true;
    truth_kind_ = "simulator ground truth";
}

void TeamSource::Load(const SourceConfig& config, const std::vector<int>& robots) {
    const auto check = [](const slam::KeyframeSourceResult& read) {
        if (!read.ok()) throw std::runtime_error(read.error);
        return read.keyframes;
    };
    slam::KeyframeSourceOptions options;
    switch (config.kind) {
        case SourceConfig::Kind::kKeyframeFolder:
            for (const int r : robots) {
                recorded_[r] = check(slam::ReadScLioSamFolder(config.paths.at(r), options));
            }
            truth_kind_ = "the folder's poses (SLAM estimates, each robot in its own frame)";
            break;
        case SourceConfig::Kind::kKitti:
            options.select_keyframes = config.select_keyframes;
            for (const int r : robots) {
                const KittiSequenceConfig& s = config.kitti.at(r);
                recorded_[r] =
                    check(slam::ReadKittiOdometryFolder(s.folder, s.poses, s.calib, options));
            }
            truth_kind_ = "KITTI ground truth (each robot in its own frame)";
            break;
        case SourceConfig::Kind::kSplit: {
            const auto all = check(slam::ReadScLioSamFolder(config.split_path, options));
            const int n = static_cast<int>(robots.size());
            Eigen::Isometry3d T_odom_world = Eigen::Isometry3d::Identity();
            for (const int r : robots) {
                T_team_odom_[r] = T_odom_world.inverse();
                for (size_t k = static_cast<size_t>(r); k < all.size(); k += n) {
                    slam::Keyframe kf = all[k];
                    truth_[r].push_back(
                        {static_cast<double>(kf.stamp_ns) * 1e-9, kf.T_odom_sensor});
                    kf.T_odom_sensor = T_odom_world * kf.T_odom_sensor;
                    recorded_[r].push_back(std::move(kf));
                }
                T_odom_world = config.T_offset_world * T_odom_world;
            }
            truth_in_team_frame_ = true;
            truth_kind_ = "the folder's poses (SLAM estimates) in robot 0's frame";
            break;
        }
        case SourceConfig::Kind::kRosbag:
            for (const int r : robots) {
                slam::RosbagSourceConfig topics = config.rosbag;
                topics.cloud_topic = WithRobotId(topics.cloud_topic, r);
                topics.odometry_topic = WithRobotId(topics.odometry_topic, r);
                recorded_[r] =
                    check(slam::ReadRosbagKeyframes(config.paths.at(r), topics, options));
            }
            truth_kind_ = "the bag's odometry (LIO-SAM estimates, each robot in its own frame)";
            break;
        case SourceConfig::Kind::kSimulator:
        case SourceConfig::Kind::kPoseGraph:  // no keyframes: LoadPoseGraphSource
            break;
    }
    for (auto& [r, keyframes] : recorded_) {
        if (max_keyframes_ > 0 && static_cast<int>(keyframes.size()) > max_keyframes_) {
            keyframes.resize(static_cast<size_t>(max_keyframes_));
        }
        if (keyframes.empty()) {
            throw std::runtime_error("source: robot " + std::to_string(r) + " has no keyframes");
        }
        for (size_t i = 0; i < keyframes.size(); ++i) {
            keyframes[i].robot = r;
            keyframes[i].index = static_cast<int>(i);
        }
        if (config.kind != SourceConfig::Kind::kSplit) {
            for (const auto& kf : keyframes) {
                truth_[r].push_back({static_cast<double>(kf.stamp_ns) * 1e-9, kf.T_odom_sensor});
            }
        } else if (truth_[r].size() > keyframes.size()) {
            truth_[r].resize(keyframes.size());
        }
    }
}

int TeamSource::NumKeyframes(int robot) const {
    if (generator_) {
        const int n = generator_->num_keyframes(robot);
        return max_keyframes_ > 0 ? std::min(n, max_keyframes_) : n;
    }
    return static_cast<int>(recorded_.at(robot).size());
}

actors::KeyframeSource TeamSource::For(int robot) const {
    auto next = std::make_shared<int>(0);
    return [this, robot, next]() -> std::optional<slam::Keyframe> {
        if (*next >= NumKeyframes(robot)) return std::nullopt;
        const int i = (*next)++;
        if (generator_) return generator_->Generate(robot, i).keyframe;
        return recorded_.at(robot)[static_cast<size_t>(i)];
    };
}

Eigen::Isometry3d TeamSource::Odometry(int robot, int index) const {
    if (generator_) return generator_->PoseOnly(robot, index).T_odom_sensor;
    return recorded_.at(robot).at(static_cast<size_t>(index)).T_odom_sensor;
}

std::optional<slam::Trajectory> TeamSource::Truth(int robot) const {
    const auto it = truth_.find(robot);
    if (it == truth_.end()) return std::nullopt;
    return it->second;
}

std::optional<Eigen::Isometry3d> TeamSource::TrueTeamOdom(int robot) const {
    const auto it = T_team_odom_.find(robot);
    if (it == T_team_odom_.end()) return std::nullopt;
    return it->second;
}

}  // namespace certislam::bin
