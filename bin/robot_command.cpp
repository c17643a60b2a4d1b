// The robot command shared by `certislam robot` and `certislam-robot`: options, configuration,
// wiring and errors; the pose-graph robot itself (source, solver and certifier actors).
#include "bin/robot_command.h"

#include <google/protobuf/util/json_util.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <thread>

#include "actors/pose_graph_node.h"
#include "actors/pose_graph_team.h"
#include "bin/command.h"
#include "bin/config/source_config.h"
#include "bin/progress.h"
#include "bin/team_result.h"
#include "transport/curve.h"

namespace certislam::bin {
namespace {

/// source.kind pose_graph: this robot's block of the graph, its solver and certifier; peers over
/// the wiring. Prints this robot's report (and writes it to OUT/robot<K>.report.json with --out);
/// returns the exit code.
int RunPoseGraphRobot(zmq::context_t& context, const actors::TeamWiring& wiring,
                      const TeamConfig& config, const RobotCommandOptions& o) {
    const int id = o.id;
    const double timeout_s = o.timeout_s;
    double cost_offset = 0.0;
    slam::RobotGraph own;
    {  // every robot reads the whole file; it keeps its own block only
        auto graphs = LoadPoseGraphSource(config.path, config.source, config.robots);
        cost_offset = slam::CostOffset(graphs);
        own = std::move(graphs.at(static_cast<size_t>(id)));
    }
    const actors::PoseGraphNodeConfig node_config =
        PoseGraphNodeConfigFrom(NodeConfigFor(config, id));
    const auto start = std::chrono::steady_clock::now();
    actors::PoseGraphNode node(context, wiring, std::move(own), node_config);
    node.Start();
    bool done = false;
    while (!done &&
           std::chrono::steady_clock::now() - start < std::chrono::duration<double>(timeout_s)) {
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
        done = node.Done();
    }
    actors::PoseGraphTeamResult result = actors::SummariseNodes<actors::PoseGraphNode>({&node});
    result.done = done;
    result.cost_offset = cost_offset;
    result.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    node.Stop();
    const bool ipc = wiring.addresses.at(id).at(actors::Edge::kCertify).rfind("ipc://", 0) == 0;
    nlohmann::json j = TeamResultJson(result, 1, ipc ? "ipc" : "tcp");
    j["robot"] = id;
    j["bytes_sent"] = result.bytes_between_robots;
    j["bytes_sent_by_actor"] = result.bytes_by_actor;
    j["out_of_plane"] = {{"m", result.out_of_plane_m}, {"rad", result.out_of_plane_rad}};
    if (result.report) {  // the anchor's certificate as its schema says (MergeRobotReports)
        std::string text;
        if (google::protobuf::util::MessageToJsonString(*result.report, &text).ok()) {
            j["certificate_report"] = nlohmann::json::parse(text);
        }
    }
    if (!o.out_dir.empty()) {
        std::ofstream(o.out_dir + "/robot" + std::to_string(id) + ".report.json")
            << j.dump(2) << "\n";
    }
    if (o.json) {
        std::printf("%s\n", j.dump(2).c_str());
    } else {
        std::printf("robot %d   objective %.10g   verdict: %s   iterations %llu   %.3f s\n", id,
                    j["cost"].get<double>(), j["verdict"].get<std::string>().c_str(),
                    static_cast<unsigned long long>(result.iterations), result.seconds);
    }
    return done ? kExitDone : kExitNotCertified;
}

/// The CURVE allow-list of the team's public keys (null without CURVE).
std::unique_ptr<transport::ZapAuthenticator> MakeZap(zmq::context_t& context,
                                                     const actors::TeamWiring& wiring) {
    if (!wiring.own_keys) return nullptr;
    std::map<std::string, std::uint32_t> allowed;
    for (const auto& [robot, key] : wiring.public_keys) allowed[key] = robot;
    return std::make_unique<transport::ZapAuthenticator>(context, allowed);
}

}  // namespace

void AddRobotCommandOptions(CLI::App& app, RobotCommandOptions* o) {
    app.option_defaults()->always_capture_default();
    app.add_option("CONFIG", o->config_path, "team configuration (YAML or JSON)")->required();
    app.add_option("--id", o->id, "this robot's id")->required();
    app.add_option("--out", o->out_dir,
                   "write robot<K>.report.json here (keyframe robots: and robot<K>.tum)");
    app.add_option("--timeout", o->timeout_s, "give up after this many seconds");
    app.add_option("--log-dir", o->log_dir, "durable log folder (overrides the config's log_dir)");
    app.add_flag("--json", o->json, "print the report as JSON");
    AddProgressOptions(app, "robot<K>.tum and robot<K>.report.json", &o->progress_s,
                       &o->snapshot_s);
}

int RunRobotCommand(const RobotCommandOptions& o, const std::string& program,
                    const KeyframeRobotFn& keyframes) {
    try {
        TeamConfig config = ReadTeamConfig(o.config_path);
        if (!o.log_dir.empty()) config.log_dir = o.log_dir;
        const bool pose_graph = config.source.kind == SourceConfig::Kind::kPoseGraph;
        if (!pose_graph && !keyframes) {
            throw std::runtime_error(config.path +
                                     ": source.kind: this robot runs pose_graph sources only "
                                     "(keyframe sources: certislam robot)");
        }
        const actors::TeamWiring wiring = NetworkWiring(config, o.id);
        zmq::context_t context;
        const auto zap = MakeZap(context, wiring);
        if (pose_graph) return RunPoseGraphRobot(context, wiring, config, o);
        return keyframes(context, wiring, config);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "%s: %s\n", program.c_str(), e.what());
        return kExitBadInput;
    }
}

}  // namespace certislam::bin
