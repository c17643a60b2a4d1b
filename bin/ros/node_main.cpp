// `certislam_node CONFIG --id K`: one robot's actor graph, exactly as `certislam robot` runs it
// (peers over tcp, CURVE with keys; the team link is not ROS), fed live by LIO-SAM's cloud and
// odometry topics, publishing the team's solution over ROS 1 until SIGINT/SIGTERM or ROS stops.
#include <CLI/CLI.hpp>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <thread>

#include "actors/ros/live_keyframes.h"
#include "actors/ros/loop_watcher.h"
#include "actors/ros/ros_bridge.h"
#include "bin/config/team_config.h"
#include "bin/ros/node_publish.h"
#include "bin/ros/ros_config.h"
#include "slam/io/trajectory_io.h"
#include "transport/curve.h"

namespace certislam::bin {
namespace {

std::atomic<bool> g_stop{false};

void OnSignal(int) { g_stop = true; }

struct Options {
    std::string config_path, out_dir, log_dir;
    int id = -1;
};

// Runs the node until a signal or ROS shutdown; returns the last status (with the TUM path).
nlohmann::json RunNode(const Options& options, int argc, char** argv) {
    TeamConfig config = LoadTeamConfig(options.config_path);
    if (!options.log_dir.empty()) config.log_dir = options.log_dir;
    const RosNodeConfig ros_config = LoadRosNodeConfig(config, options.id);
    const actors::TeamWiring wiring = NetworkWiring(config, options.id);
    const actors::RobotNodeConfig node_config = NodeConfigFor(config, options.id);
    actors::RosBridge::Init(&argc, argv, "certislam_robot" + std::to_string(options.id));

    zmq::context_t context;
    std::unique_ptr<transport::ZapAuthenticator> zap;
    if (wiring.own_keys) {
        std::map<std::string, std::uint32_t> allowed;
        for (const auto& [robot, key] : wiring.public_keys) allowed[key] = robot;
        zap = std::make_unique<transport::ZapAuthenticator>(context, allowed);
    }
    actors::LiveKeyframes live(ros_config.ingest);
    actors::LoopWatcherActor watcher(context, wiring);
    actors::RobotNode node(context, wiring, live.Source(), node_config);
    actors::RosBridge bridge(
        ros_config.bridge,
        [&live](std::int64_t stamp, const std::string& frame, slam::PointCloud cloud) {
            live.OnCloud(stamp, frame, std::move(cloud));
        },
        [&live](std::int64_t stamp, const std::string& frame, const Eigen::Isometry3d& T) {
            live.OnOdometry(stamp, frame, T);
        });
    watcher.Start();
    node.Start();
    NodePublisher publisher(ros_config, bridge, live, node, watcher, options.id,
                            node_config.mapper.map.tsdf.voxel_size_m);
    std::fprintf(stderr, "certislam_node %d: listening on %s and %s, publishing under %s\n",
                 options.id, ros_config.bridge.cloud_topic.c_str(),
                 ros_config.bridge.odometry_topic.c_str(),
                 ros_config.bridge.output_namespace.c_str());
    const auto period = std::chrono::duration<double>(ros_config.publish_period_s);
    while (!g_stop && bridge.Ok()) {
        publisher.Tick();
        std::this_thread::sleep_for(period);
    }
    publisher.Tick();
    bridge.StopSubscriptions();
    live.Close();
    const actors::SolverSnapshot snapshot = node.Snapshot();
    node.Stop();
    watcher.Stop();
    nlohmann::json status = publisher.Status();
    if (!options.out_dir.empty()) {
        std::filesystem::create_directories(options.out_dir);
        const std::string path = options.out_dir + "/robot" + std::to_string(options.id) + ".tum";
        std::string error;
        if (!slam::WriteTrajectory(path, snapshot.trajectory, slam::TrajectoryFormat::kTum,
                                   &error)) {
            throw std::runtime_error(error);
        }
        status["tum"] = path;
    }
    return status;
}

int Main(int argc, char** argv) {
    CLI::App app{"One robot of a team configuration, fed live by LIO-SAM over ROS 1"};
    app.name("certislam_node");
    Options options;
    app.add_option("CONFIG", options.config_path, "team configuration (JSON)")->required();
    app.add_option("--id", options.id, "this robot's id")->required();
    app.add_option("--out", options.out_dir, "write robot<K>.tum here on exit");
    app.add_option("--log-dir", options.log_dir, "durable log folder (overrides the config's)");
    app.allow_extras();  // ROS remappings (name:=value) and roslaunch's __name/__log arguments
    CLI11_PARSE(app, argc, argv);
    std::signal(SIGINT, OnSignal);
    std::signal(SIGTERM, OnSignal);
    try {
        const nlohmann::json status = RunNode(options, argc, argv);
        std::printf("%s\n", status.dump().c_str());
        return 0;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "certislam_node: %s\n", e.what());
        return 1;
    }
}

}  // namespace
}  // namespace certislam::bin

int main(int argc, char** argv) { return certislam::bin::Main(argc, argv); }
