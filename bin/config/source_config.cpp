// The `source` part of a team configuration: checked against the team (every error names the
// file and the key), and a pose-graph source's graph read and split into the team's robots.
#include "bin/config/source_config.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <stdexcept>

#include "slam/io/g2o_io.h"
#include "slam/io/multirobot_io.h"
#include "slam/sim/sim_scenarios.h"

namespace certislam::bin {
namespace {

constexpr double kDegToRad = M_PI / 180.0;

std::runtime_error FieldError(const std::string& config_path, const std::string& field,
                              const std::string& rule) {
    return std::runtime_error(config_path + ": source." + field + ": " + rule);
}

/// Every robot of the team has an entry in `entries` (source.FIELD.<robot>), and no other robot.
template <class T>
void OnePerRobot(const std::map<int, T>& entries, const char* field, const std::string& config_path,
                 const std::vector<int>& robots) {
    for (const int r : robots) {
        if (!entries.count(r)) {
            throw FieldError(config_path, std::string(field) + "." + std::to_string(r),
                             "missing (one entry per robot of the team)");
        }
    }
    if (entries.size() != robots.size()) {
        throw FieldError(config_path, field, "has entries for robots not in the team");
    }
}

/// T_offset_world from the offset's translation and roll, pitch, yaw (degrees, Z*Y*X).
Eigen::Isometry3d Offset(const Eigen::Vector3d& xyz, const Eigen::Vector3d& rpy_deg) {
    const Eigen::Vector3d rpy = rpy_deg * kDegToRad;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = (Eigen::AngleAxisd(rpy.z(), Eigen::Vector3d::UnitZ()) *
                  Eigen::AngleAxisd(rpy.y(), Eigen::Vector3d::UnitY()) *
                  Eigen::AngleAxisd(rpy.x(), Eigen::Vector3d::UnitX()))
                     .toRotationMatrix();
    T.translation() = xyz;
    return T;
}

bool HasRanges(const SourceConfig& config) {
    return std::any_of(config.ranges.begin(), config.ranges.end(), [](const auto& entry) {
        return entry.second != std::pair{0, 0};
    });
}

/// source.ranges: one per robot, in robot order, each starting where the previous one ends.
void CheckRanges(const std::string& config_path, const std::vector<int>& robots,
                 const SourceConfig& config) {
    OnePerRobot(config.ranges, "ranges", config_path, robots);
    int end = 0;
    for (const int r : robots) {
        const auto [begin, stop] = config.ranges.at(r);
        const std::string key = "ranges." + std::to_string(r);
        if (begin < end) {
            throw FieldError(config_path, key + ".begin",
                             std::to_string(begin) + " overlaps robot " + std::to_string(r - 1) +
                                 "'s range, which ends at " + std::to_string(end));
        }
        if (begin > end) {
            throw FieldError(config_path, key + ".begin",
                             std::to_string(begin) + " leaves vertices [" + std::to_string(end) +
                                 ", " + std::to_string(begin) + ") to no robot");
        }
        if (stop <= begin) {
            throw FieldError(config_path, key + ".end",
                             std::to_string(stop) + ": must be > begin = " + std::to_string(begin));
        }
        end = stop;
    }
}

/// The partition of a g2o file's n vertices by source.ranges (checked by CheckRanges).
slam::Partition RangePartition(const std::string& config_path, const std::vector<int>& robots,
                               const SourceConfig& config, int n) {
    slam::Partition partition;
    for (const int r : robots) partition.begin.push_back(config.ranges.at(r).first);
    const int end = config.ranges.at(robots.back()).second;
    const std::string key = "ranges." + std::to_string(robots.back()) + ".end";
    if (end != n) {
        throw FieldError(config_path, key,
                         std::to_string(end) +
                             (end > n ? " is beyond" : " ends before the end of") +
                             " the graph's " + std::to_string(n) + " vertices");
    }
    partition.begin.push_back(n);
    return partition;
}

}  // namespace

std::string WithRobotId(std::string text, int robot) {
    const std::string key = "{robot}";
    for (auto at = text.find(key); at != std::string::npos; at = text.find(key, at)) {
        text.replace(at, key.size(), std::to_string(robot));
    }
    return text;
}

std::vector<slam::RobotGraph> LoadPoseGraphSource(const std::string& config_path,
                                                  const SourceConfig& config,
                                                  const std::vector<int>& robots) {
    const bool folder = std::filesystem::is_directory(config.graph_path);
    const auto read =
        folder ? slam::ReadMultiRobotCsv(config.graph_path) : slam::ReadG2o(config.graph_path);
    if (!read.ok()) throw std::runtime_error(read.error);
    slam::Partition partition;
    try {
        if (HasRanges(config)) {  // a folder's robots in file order, then split by vertex
            partition = RangePartition(config_path, robots, config, read.graph.n);
        } else if (folder) {
            partition = slam::PartitionFromIds(read.graph);
            if (partition.num_robots() != static_cast<int>(robots.size())) {
                throw FieldError(config_path, "graph",
                                 "the folder holds " + std::to_string(partition.num_robots()) +
                                     " robots, the team " + std::to_string(robots.size()));
            }
        } else {
            partition = slam::ContiguousPartition(read.graph.n, static_cast<int>(robots.size()));
        }
        return slam::SplitGraph(read.graph, partition);
    } catch (const std::invalid_argument& e) {
        throw std::runtime_error(config.graph_path + ": " + e.what());
    }
}

void FinishSourceConfig(const std::string& config_path, const std::vector<int>& robots,
                        SourceConfig* config) {
    using Kind = SourceConfig::Kind;
    const auto non_empty = [&](const std::string& path, const std::string& field) {
        if (path.empty()) throw FieldError(config_path, field, "missing: must be a path");
    };
    if (config->kind == Kind::kKeyframeFolder || config->kind == Kind::kRosbag) {
        OnePerRobot(config->paths, "paths", config_path, robots);
        for (const auto& [r, path] : config->paths) non_empty(path, "paths." + std::to_string(r));
    }
    if (config->kind == Kind::kRosbag) {
        const auto& bag = config->rosbag;
        if (bag.cloud_topic.empty() || bag.odometry_topic.empty()) {
            throw FieldError(config_path,
                             bag.cloud_topic.empty() ? "cloud_topic" : "odometry_topic",
                             "must be a non-empty topic name");
        }
    }
    if (config->kind == Kind::kKitti) {
        OnePerRobot(config->kitti, "sequences", config_path, robots);
        for (const auto& [r, s] : config->kitti) {
            const std::string field = "sequences." + std::to_string(r) + ".";
            non_empty(s.folder, field + "folder");
            non_empty(s.poses, field + "poses");
            non_empty(s.calib, field + "calib");
        }
    }
    if (config->kind == Kind::kSplit) {
        non_empty(config->split_path, "path");
        if (config->split_robots != 0 && config->split_robots != static_cast<int>(robots.size())) {
            throw FieldError(config_path, "robots", "must equal the team's size");
        }
        config->T_offset_world = Offset(config->offset_xyz_m, config->offset_rpy_deg);
    }
    if (config->kind == Kind::kPoseGraph) {
        non_empty(config->graph_path, "graph");
        if (HasRanges(*config)) CheckRanges(config_path, robots, *config);
    }
    config->simulator.num_robots = static_cast<int>(robots.size());
    if (config->kind == Kind::kSimulator && !config->scenario.empty()) {
        auto scenario = slam::MakeScenario(config->scenario, static_cast<int>(robots.size()),
                                           config->simulator.seed);
        if (!scenario) {
            std::string names;
            for (const auto& n : slam::ScenarioNames()) names += (names.empty() ? "" : ", ") + n;
            throw FieldError(config_path, "scenario", "must be one of " + names);
        }
        config->simulator = scenario->config;
    }
}

}  // namespace certislam::bin
