// `certislam robot CONFIG --id K [--out DIR] [--json]`: one robot's actor graph in this process;
// its peers are other processes reached over tcp, with CURVE when the configuration names keys
// (distributed multi-host mode). With mapping on, its TSDF mapper's mesh goes to
// DIR/robot<K>.mesh.ply (the anchor's holds every robot's submaps; see mapping.team_map).
#include <google/protobuf/util/json_util.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <thread>

#include "actors/pose_graph_node.h"
#include "actors/pose_graph_team.h"
#include "bin/command.h"
#include "bin/config/team_config.h"
#include "bin/progress.h"
#include "bin/solve_distributed.h"
#include "bin/stop_within.h"
#include "bin/verdict.h"
#include "transport/curve.h"

namespace certislam::bin {
namespace {

/// source.kind pose_graph: this robot's block of the graph, its solver and certifier; peers over
/// the wiring. Prints this robot's report; returns the exit code.
int RunPoseGraphRobot(zmq::context_t& context, const actors::TeamWiring& wiring,
                      const TeamConfig& config, int id, double timeout_s, bool json) {
    const auto graphs = LoadPoseGraphSource(config.path, config.source, config.robots);
    const actors::PoseGraphNodeConfig node_config =
        PoseGraphNodeConfigFrom(NodeConfigFor(config, id));
    const auto start = std::chrono::steady_clock::now();
    actors::PoseGraphNode node(context, wiring, graphs.at(static_cast<size_t>(id)), node_config);
    node.Start();
    bool done = false;
    while (!done &&
           std::chrono::steady_clock::now() - start < std::chrono::duration<double>(timeout_s)) {
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
        done = node.Done();
    }
    actors::PoseGraphTeamResult result = actors::SummariseNodes({&node});
    result.done = done;
    result.cost_offset = slam::CostOffset(graphs);
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
    if (json) {
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

/// The report's counters of the robot's actors (bytes by actor, matcher, certifier).
void AddActorCounters(actors::RobotNode& node,
                      const std::map<std::string, std::uint64_t>& bytes_by_actor,
                      nlohmann::json* report) {
    (*report)["bytes_sent_by_actor"] = bytes_by_actor;
    const actors::LoopMatcherActor& matcher = node.Matcher();
    (*report)["matcher"] = {{"verified", matcher.Verified()},
                            {"rejected", matcher.Rejected()},
                            {"clouds_requested", matcher.CloudsRequested()},
                            {"skipped_by_gate", matcher.Skipped()}};
    const actors::CertifierActor& certifier = node.Certifier();
    (*report)["certifier"] = {{"rounds", certifier.Rounds()},
                              {"lanczos_steps", certifier.LanczosSteps()},
                              {"settled_skips", certifier.SettledSkips()},
                              {"fallbacks", certifier.Fallbacks()}};
}

int RunRobot(int argc, char** argv) {
    CLI::App app{"One robot of a configuration; peers over tcp (CURVE with keys)"};
    app.name("certislam robot");
    std::string config_path, out_dir;
    int id = -1;
    bool json = false;
    double timeout_s = 300.0;
    app.option_defaults()->always_capture_default();
    app.add_option("CONFIG", config_path, "team configuration (YAML or JSON)")->required();
    app.add_option("--id", id, "this robot's id")->required();
    app.add_option("--out", out_dir, "write robot<K>.tum and robot<K>.report.json here");
    app.add_option("--timeout", timeout_s, "give up after this many seconds");
    std::string log_dir;
    app.add_option("--log-dir", log_dir, "durable log folder (overrides the config's log_dir)");
    app.add_flag("--json", json, "print the report as JSON");
    double progress_s = 2.0, snapshot_s = 5.0;
    AddProgressOptions(app, "robot<K>.tum and robot<K>.report.json", &progress_s, &snapshot_s);
    CLI11_PARSE(app, argc, argv);

    const auto start = std::chrono::steady_clock::now();
    try {
        TeamConfig config = LoadTeamConfig(config_path);
        if (!log_dir.empty()) config.log_dir = log_dir;
        const actors::TeamWiring wiring = NetworkWiring(config, id);
        const TeamSource source(config.source, config.robots);
        zmq::context_t context;
        const auto zap = MakeZap(context, wiring);
        if (config.source.kind == SourceConfig::Kind::kPoseGraph) {
            return RunPoseGraphRobot(context, wiring, config, id, timeout_s, json);
        }
        const actors::RobotNodeConfig node_config = NodeConfigFor(config, id);
        actors::RobotNode node(context, wiring, source.For(id), node_config);
        node.Start();
        const auto states = [&] { return std::vector<actors::SolverSnapshot>{node.Snapshot()}; };
        Progress progress(
            "certislam robot " + std::to_string(id), MakeProgressConfig(progress_s, snapshot_s),
            [&] {
                if (out_dir.empty()) return;
                const std::string now = WriteTeamOutputs(
                    out_dir, {id}, states(), source, node.BytesSentToPeers(),
                    std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(),
                    "");
                std::ofstream(out_dir + "/robot" + std::to_string(id) + ".report.json")
                    << now << "\n";
            });
        const bool done =
            WaitWithProgress([&] { return node.Done(); }, start, timeout_s, &progress, states);
        const double seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        const auto snapshot = node.Snapshot();
        const auto bytes = node.BytesSentToPeers();
        const auto bytes_by_actor = node.BytesSentToPeersByActor();
        // After the deadline the mapper is not waited for: no mesh then.
        const nlohmann::json mesh = done ? WriteRobotMesh(node, node_config, id, out_dir) : nullptr;
        node.RequestStop();
        auto report = nlohmann::json::parse(
            WriteTeamOutputs(out_dir, {id}, {snapshot}, source, bytes, seconds, ""));
        AddActorCounters(node, bytes_by_actor, &report);
        if (!mesh.is_null()) report["mesh"] = mesh;
        const std::string text = report.dump(2);
        if (!out_dir.empty()) {
            std::ofstream(out_dir + "/robot" + std::to_string(id) + ".report.json") << text << "\n";
        }
        if (json) {
            std::printf("%s\n", text.c_str());
        } else {
            std::printf("%s%s\n", TeamReportText(text).c_str(),
                        done ? "done: certified" : "not certified before the timeout");
        }
        const int code = done ? kExitDone : kExitNotCertified;
        StopWithin([&] { node.Stop(); }, kStopGrace, code);
        return code;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "certislam robot: %s\n", e.what());
        return kExitBadInput;
    }
}

const Registrar kRegistrar{"robot", "one robot of a configuration; peers over tcp with CURVE",
                           RunRobot};

}  // namespace
}  // namespace certislam::bin
