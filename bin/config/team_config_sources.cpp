// Team keyframe sources: the `source` configuration, the readers behind it, ground truth.
#include "bin/config/team_config_sources.h"

#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "slam/io/keyframe_sources_io.h"
#include "slam/io/rosbag/rosbag_source_io.h"

namespace certislam::bin {
namespace {

using nlohmann::json;

constexpr double kDegToRad = M_PI / 180.0;

std::runtime_error FieldError(const std::string& config_path, const std::string& field,
                              const std::string& rule) {
    return std::runtime_error(config_path + ": source." + field + ": " + rule);
}

/// `robot` -> value of an object keyed by robot id ("0", "1", ...), one entry per robot.
template <class T, class Parse>
std::map<int, T> PerRobot(const json& source, const char* field, const std::string& config_path,
                          const std::vector<int>& robots, Parse parse) {
    if (!source.contains(field) || !source.at(field).is_object()) {
        throw FieldError(config_path, field, "missing, or not an object {\"0\": ..., \"1\": ...}");
    }
    std::map<int, T> out;
    for (const int r : robots) {
        const std::string key = std::to_string(r);
        if (!source.at(field).contains(key)) {
            throw FieldError(config_path, std::string(field) + "." + key,
                             "missing (one entry per robot of the team)");
        }
        out[r] = parse(source.at(field).at(key), std::string(field) + "." + key);
    }
    if (source.at(field).size() != robots.size()) {
        throw FieldError(config_path, field, "has entries for robots not in the team");
    }
    return out;
}

Eigen::Vector3d ReadVector3(const json& j, const char* key, const std::string& config_path,
                            const std::string& field) {
    if (!j.contains(key)) return Eigen::Vector3d::Zero();
    const auto v = j.at(key).get<std::vector<double>>();
    if (v.size() != 3 || !std::isfinite(v[0]) || !std::isfinite(v[1]) || !std::isfinite(v[2])) {
        throw FieldError(config_path, field + "." + key, "must be 3 finite numbers");
    }
    return {v[0], v[1], v[2]};
}

/// "offset": {"xyz_m": [x, y, z], "rpy_deg": [roll, pitch, yaw]} -> T_offset_world.
Eigen::Isometry3d ReadOffset(const json& j, const std::string& config_path) {
    const Eigen::Vector3d xyz = ReadVector3(j, "xyz_m", config_path, "offset");
    const Eigen::Vector3d rpy = ReadVector3(j, "rpy_deg", config_path, "offset") * kDegToRad;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = (Eigen::AngleAxisd(rpy.z(), Eigen::Vector3d::UnitZ()) *
                  Eigen::AngleAxisd(rpy.y(), Eigen::Vector3d::UnitY()) *
                  Eigen::AngleAxisd(rpy.x(), Eigen::Vector3d::UnitX()))
                     .toRotationMatrix();
    T.translation() = xyz;
    return T;
}

SourceConfig::Kind ReadKind(const json& source, const std::string& config_path) {
    const std::string kind = source.value("kind", "simulator");
    if (kind == "simulator") return SourceConfig::Kind::kSimulator;
    if (kind == "keyframe_folder") return SourceConfig::Kind::kKeyframeFolder;
    if (kind == "kitti") return SourceConfig::Kind::kKitti;
    if (kind == "split") return SourceConfig::Kind::kSplit;
    if (kind == "rosbag") return SourceConfig::Kind::kRosbag;
    throw FieldError(
        config_path, "kind",
        "\"" + kind + "\" is not one of simulator, keyframe_folder, kitti, split, rosbag");
}

/// "cloud_topic", "odometry_topic", "max_stamp_gap_s", "cloud_frame" (auto | sensor | odom).
slam::RosbagSourceConfig ReadRosbagConfig(const json& source, const std::string& config_path) {
    slam::RosbagSourceConfig rosbag;
    rosbag.cloud_topic = source.value("cloud_topic", rosbag.cloud_topic);
    rosbag.odometry_topic = source.value("odometry_topic", rosbag.odometry_topic);
    rosbag.max_stamp_gap_s = source.value("max_stamp_gap_s", rosbag.max_stamp_gap_s);
    if (!(rosbag.max_stamp_gap_s >= 0.0) || !std::isfinite(rosbag.max_stamp_gap_s)) {
        throw FieldError(config_path, "max_stamp_gap_s", "must be a finite number >= 0");
    }
    const std::string frame = source.value("cloud_frame", "auto");
    if (frame == "auto") {
        rosbag.cloud_frame = slam::RosbagCloudFrame::kAuto;
    } else if (frame == "sensor") {
        rosbag.cloud_frame = slam::RosbagCloudFrame::kSensor;
    } else if (frame == "odom") {
        rosbag.cloud_frame = slam::RosbagCloudFrame::kOdom;
    } else {
        throw FieldError(config_path, "cloud_frame",
                         "\"" + frame + "\" is not one of auto, sensor, odom");
    }
    if (rosbag.cloud_topic.empty() || rosbag.odometry_topic.empty()) {
        throw FieldError(config_path, rosbag.cloud_topic.empty() ? "cloud_topic" : "odometry_topic",
                         "must be a non-empty topic name");
    }
    return rosbag;
}

}  // namespace

SourceConfig ReadSourceConfig(const json& source, const std::string& config_path,
                              const std::vector<int>& robots) {
    const std::string dir = std::filesystem::path(config_path).parent_path().string();
    const auto resolve = [&](const std::string& p) {
        return p.empty() || p.front() == '/' ? p : (std::filesystem::path(dir) / p).string();
    };
    const auto path_of = [&](const json& j, const std::string& field) {
        if (!j.is_string() || j.get<std::string>().empty()) {
            throw FieldError(config_path, field, "must be a non-empty path");
        }
        return resolve(j.get<std::string>());
    };
    SourceConfig config;
    config.kind = ReadKind(source, config_path);
    config.max_keyframes = source.value("max_keyframes", 0);
    if (config.max_keyframes < 0) throw FieldError(config_path, "max_keyframes", "must be >= 0");
    switch (config.kind) {
        case SourceConfig::Kind::kSimulator:
            config.simulator.seed = source.value("seed", config.simulator.seed);
            config.simulator.keyframe_spacing_m =
                source.value("keyframe_spacing_m", config.simulator.keyframe_spacing_m);
            config.simulator.num_robots = static_cast<int>(robots.size());
            break;
        case SourceConfig::Kind::kKeyframeFolder:
            config.paths = PerRobot<std::string>(source, "paths", config_path, robots, path_of);
            break;
        case SourceConfig::Kind::kRosbag:
            config.paths = PerRobot<std::string>(source, "paths", config_path, robots, path_of);
            config.rosbag = ReadRosbagConfig(source, config_path);
            break;
        case SourceConfig::Kind::kKitti:
            config.select_keyframes = source.value("select_keyframes", true);
            config.kitti = PerRobot<KittiSequenceConfig>(
                source, "sequences", config_path, robots, [&](const json& j, const std::string& f) {
                    if (!j.is_object()) throw FieldError(config_path, f, "must be an object");
                    for (const char* k : {"folder", "poses", "calib"}) {
                        if (!j.contains(k)) throw FieldError(config_path, f + "." + k, "missing");
                    }
                    return KittiSequenceConfig{path_of(j.at("folder"), f + ".folder"),
                                               path_of(j.at("poses"), f + ".poses"),
                                               path_of(j.at("calib"), f + ".calib")};
                });
            break;
        case SourceConfig::Kind::kSplit:
            if (!source.contains("path")) throw FieldError(config_path, "path", "missing");
            config.split_path = path_of(source.at("path"), "path");
            if (source.value("robots", static_cast<int>(robots.size())) !=
                static_cast<int>(robots.size())) {
                throw FieldError(config_path, "robots", "must equal the team's size");
            }
            if (source.contains("offset")) {
                config.T_offset_world = ReadOffset(source.at("offset"), config_path);
            }
            break;
    }
    return config;
}

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
                recorded_[r] =
                    check(slam::ReadRosbagKeyframes(config.paths.at(r), config.rosbag, options));
            }
            truth_kind_ = "the bag's odometry (LIO-SAM estimates, each robot in its own frame)";
            break;
        case SourceConfig::Kind::kSimulator:
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
