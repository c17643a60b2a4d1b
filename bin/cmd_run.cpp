// `certislam run CONFIG [--out DIR] [--json]`: every robot of the configuration in one process,
// each a full actor graph, the robots talking over inproc (single-binary local mode). With
// mapping on, each robot's mapper mesh goes to DIR/robot<K>.mesh.ply (the anchor's is the team's).
#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <thread>

#include "bin/command.h"
#include "bin/config/team_config.h"
#include "bin/solve_distributed.h"
#include "bin/stop_within.h"

namespace certislam::bin {
namespace {

/// source.kind pose_graph: each robot its block of the graph, solver and certifier (no front end).
int RunPoseGraph(const TeamConfig& config, double timeout_s, bool json) {
    const auto graphs = LoadPoseGraphSource(config.path, config.source, config.robots);
    actors::PoseGraphNodeConfig node;
    node.solver = config.node.solver;
    node.certifier = config.node.certifier;
    node.quiet = config.node.quiet;
    const auto result =
        actors::RunPoseGraphTeam(graphs, node, std::chrono::duration<double>(timeout_s));
    nlohmann::json j = TeamResultJson(result, static_cast<int>(graphs.size()));
    j["graph"] = config.source.graph_path;
    if (json) {
        std::printf("%s\n", j.dump(2).c_str());
    } else {
        std::printf("objective %.10g   verdict: %s   team iterations %llu   %.3f s\n",
                    j["cost"].get<double>(), j["verdict"].get<std::string>().c_str(),
                    j["iterations"].get<unsigned long long>(), j["seconds"].get<double>());
    }
    return j["certified"].get<bool>() ? kExitDone : kExitNotCertified;
}

int RunRun(int argc, char** argv) {
    CLI::App app{"All robots of a configuration in one process, over inproc"};
    app.name("certislam run");
    std::string config_path, out_dir;
    bool json = false;
    double timeout_s = 300.0;
    app.option_defaults()->always_capture_default();
    app.add_option("CONFIG", config_path, "team configuration (YAML or JSON)")->required();
    app.add_option("--out", out_dir,
                   "write report.json, robot<k>.tum, robot<k>.ground_truth.tum (where the source "
                   "has a reference) and robot<k>.mesh.ply (mapping on) here");
    app.add_option("--timeout", timeout_s, "give up after this many seconds");
    app.add_flag("--json", json, "print the report as JSON");
    CLI11_PARSE(app, argc, argv);

    const auto start = std::chrono::steady_clock::now();
    try {
        const TeamConfig config = LoadTeamConfig(config_path);
        if (config.source.kind == SourceConfig::Kind::kPoseGraph) {
            return RunPoseGraph(config, timeout_s, json);
        }
        const TeamSource source(config.source, config.robots);
        zmq::context_t context;
        std::vector<std::unique_ptr<actors::RobotNode>> nodes;
        std::vector<actors::RobotNodeConfig> node_configs;  // NodeConfigFor checks the logs: once
        for (int r : config.robots) {
            node_configs.push_back(NodeConfigFor(config, r));
            nodes.push_back(
                std::make_unique<actors::RobotNode>(context, actors::InprocWiring(r, config.robots),
                                                    source.For(r), node_configs.back()));
        }
        for (auto& node : nodes) node->Start();
        bool done = false;
        const auto deadline = start + std::chrono::duration<double>(timeout_s);
        while (!done && std::chrono::steady_clock::now() < deadline) {
            std::this_thread::sleep_for(std::chrono::milliseconds(50));
            done = true;
            for (auto& node : nodes) done = done && node->Done();
        }
        const double seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        std::vector<actors::SolverSnapshot> snapshots;
        std::uint64_t bytes = 0;
        for (auto& node : nodes) {
            snapshots.push_back(node->Snapshot());
            bytes += node->BytesSentToPeers();
        }
        std::vector<nlohmann::json> meshes;  // the anchor's fuses the team's submaps
        for (size_t k = 0; k < nodes.size() && done; ++k) {  // after the deadline: no meshes
            meshes.push_back(WriteRobotMesh(*nodes[k], node_configs[k], config.robots[k], out_dir));
        }
        for (auto& node : nodes) node->RequestStop();  // all at once: their handlers end together
        const std::string report = WriteTeamOutputs(out_dir, config.robots, snapshots, source,
                                                    bytes, seconds, "report.json", meshes);
        if (json) {
            std::printf("%s\n", report.c_str());
        } else {
            std::printf("%s%s\n", TeamReportText(report).c_str(),
                        done ? "done: certified" : "not certified before the timeout");
        }
        const int code = done ? kExitDone : kExitNotCertified;
        StopWithin(
            [&] {
                for (auto& node : nodes) node->Stop();
            },
            kStopGrace, code);
        return code;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "certislam run: %s\n", e.what());
        return kExitBadInput;
    }
}

const Registrar kRegistrar{"run", "all robots of a configuration in one process (inproc)", RunRun};

}  // namespace
}  // namespace certislam::bin
