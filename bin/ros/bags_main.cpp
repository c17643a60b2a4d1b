// `certislam_ros_bags CONFIG --out DIR`: per robot of the configuration's simulated mission, a
// LIO-SAM-style ROS 1 bag DIR/robot<K>.bag (odometry and cloud_registered_raw, the clouds in the
// odometry frame, on the "ros" object's topics) and its ground truth DIR/robot<K>.truth.tum in
// the frame the nodes publish in (the solution's: robot 0's first keyframe; see
// WriteTeamOutputs): the input of deploy/ros_demo.sh.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "bin/config/team_config.h"
#include "bin/ros/ros_config.h"
#include "slam/io/rosbag/rosbag_source_io.h"
#include "slam/io/trajectory_io.h"

namespace certislam::bin {
namespace {

int Main(int argc, char** argv) {
    CLI::App app{"LIO-SAM-style ROS 1 bags of a configuration's simulated mission"};
    app.name("certislam_ros_bags");
    std::string config_path, out_dir;
    app.add_option("CONFIG", config_path, "team configuration (JSON, simulator source)")
        ->required();
    app.add_option("--out", out_dir, "write robot<K>.bag and robot<K>.truth.tum here")->required();
    CLI11_PARSE(app, argc, argv);
    try {
        const TeamConfig config = LoadTeamConfig(config_path);
        if (config.source.kind != SourceConfig::Kind::kSimulator) {
            throw std::runtime_error(config_path + ": source.kind: must be simulator");
        }
        const TeamSource source(config.source, config.robots);
        // Truth is in robot 0's odometry frame; the solution in robot 0's first keyframe's.
        const Eigen::Isometry3d T_map_team =
            (*source.TrueTeamOdom(0) * source.Odometry(0, 0)).inverse();
        std::filesystem::create_directories(out_dir);
        nlohmann::json out;
        for (const int r : config.robots) {
            const RosNodeConfig ros = LoadRosNodeConfig(config, r);
            slam::RosbagSourceConfig topics;
            topics.cloud_topic = ros.bridge.cloud_topic;
            topics.odometry_topic = ros.bridge.odometry_topic;
            topics.cloud_frame = slam::RosbagCloudFrame::kOdom;
            std::vector<slam::Keyframe> keyframes;
            const actors::KeyframeSource next = source.For(r);
            while (auto kf = next()) keyframes.push_back(std::move(*kf));
            slam::Trajectory truth = *source.Truth(r);
            for (slam::StampedPose& p : truth) p.T_world_body = T_map_team * p.T_world_body;
            const std::string base = out_dir + "/robot" + std::to_string(r);
            std::string error;
            if (!slam::WriteRosbagKeyframes(base + ".bag", keyframes, topics, &error) ||
                !slam::WriteTrajectory(base + ".truth.tum", truth, slam::TrajectoryFormat::kTum,
                                       &error)) {
                throw std::runtime_error(error);
            }
            out[std::to_string(r)] = {{"bag", base + ".bag"},
                                      {"truth", base + ".truth.tum"},
                                      {"keyframes", keyframes.size()},
                                      {"first_stamp_ns", keyframes.front().stamp_ns},
                                      {"last_stamp_ns", keyframes.back().stamp_ns}};
        }
        std::printf("%s\n", out.dump().c_str());
        return 0;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "certislam_ros_bags: %s\n", e.what());
        return 1;
    }
}

}  // namespace
}  // namespace certislam::bin

int main(int argc, char** argv) { return certislam::bin::Main(argc, argv); }
