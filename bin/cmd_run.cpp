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
#include "bin/progress.h"
#include "bin/solve_distributed.h"
#include "bin/stop_within.h"
#include "transport/context.h"

namespace certislam::bin {
namespace {

/// source.kind pose_graph: each robot its block of the graph, solver and certifier (no front end).
int RunPoseGraph(const TeamConfig& config, double timeout_s, bool json) {
    const auto graphs = LoadPoseGraphSource(config.path, config.source, config.robots);
    const actors::PoseGraphNodeConfig node = PoseGraphNodeConfigFrom(config.node);
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

/// What `run`'s command line says.
struct RunOptions {
    std::string config_path, out_dir;
    bool json = false;
    double timeout_s = 300.0, progress_s = 2.0, snapshot_s = 5.0;
};

/// Every robot's actor graph over inproc until all are certified and quiet or the deadline;
/// writes and prints the report; returns the exit code.
int RunTeam(const TeamConfig& config, const RunOptions& o,
            std::chrono::steady_clock::time_point start) {
    const TeamSource source(config.source, config.robots);
    zmq::context_t context;
    transport::ReserveSockets(
        context, actors::InprocTeamSockets(static_cast<int>(config.robots.size()), true));
    std::vector<std::unique_ptr<actors::RobotNode>> nodes;
    std::vector<actors::RobotNodeConfig> node_configs;  // NodeConfigFor checks the logs: once
    for (int r : config.robots) {
        node_configs.push_back(NodeConfigFor(config, r));
        nodes.push_back(std::make_unique<actors::RobotNode>(
            context, actors::InprocWiring(r, config.robots), source.For(r), node_configs.back()));
    }
    for (auto& node : nodes) node->Start();
    const auto elapsed = [&] {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    };
    const auto states = [&] {
        std::vector<actors::SolverSnapshot> now;
        now.reserve(nodes.size());
        for (auto& node : nodes) now.push_back(node->Snapshot());
        return now;
    };
    const auto sent = [&] {
        std::vector<const actors::RobotNode*> all;  // the anchor (the first robot) first
        all.reserve(nodes.size());
        for (auto& node : nodes) all.push_back(node.get());
        return actors::SummariseNodes(all);
    };
    Progress progress("certislam run", MakeProgressConfig(o.progress_s, o.snapshot_s), [&] {
        if (!o.out_dir.empty()) {
            WriteTeamOutputs(o.out_dir, config.robots, states(), source, sent(), elapsed(),
                             "report.json");
        }
    });
    const bool done = WaitWithProgress(
        [&] {
            bool all = true;
            for (auto& node : nodes) all = all && node->Done();
            return all;
        },
        start, o.timeout_s, &progress, states);
    const double seconds = elapsed();
    const std::vector<actors::SolverSnapshot> snapshots = states();
    const actors::PoseGraphTeamResult team = sent();
    std::vector<nlohmann::json> meshes;                  // the anchor's fuses the team's submaps
    for (size_t k = 0; k < nodes.size() && done; ++k) {  // after the deadline: no meshes
        meshes.push_back(WriteRobotMesh(*nodes[k], node_configs[k], config.robots[k], o.out_dir));
    }
    for (auto& node : nodes) node->RequestStop();  // all at once: their handlers end together
    const std::string report = WriteTeamOutputs(o.out_dir, config.robots, snapshots, source, team,
                                                seconds, "report.json", meshes);
    if (o.json) {
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
}

int RunRun(int argc, char** argv) {
    CLI::App app{"All robots of a configuration in one process, over inproc"};
    app.name("certislam run");
    RunOptions o;
    app.option_defaults()->always_capture_default();
    app.add_option("CONFIG", o.config_path, "team configuration (YAML or JSON)")->required();
    app.add_option("--out", o.out_dir,
                   "write report.json, robot<k>.tum, robot<k>.ground_truth.tum (where the source "
                   "has a reference) and robot<k>.mesh.ply (mapping on) here");
    app.add_option("--timeout", o.timeout_s, "give up after this many seconds");
    app.add_flag("--json", o.json, "print the report as JSON");
    AddProgressOptions(app, "trajectories and report.json", &o.progress_s, &o.snapshot_s);
    CLI11_PARSE(app, argc, argv);

    const auto start = std::chrono::steady_clock::now();
    try {
        const TeamConfig config = LoadTeamConfig(o.config_path);
        if (config.source.kind == SourceConfig::Kind::kPoseGraph) {
            return RunPoseGraph(config, o.timeout_s, o.json);
        }
        return RunTeam(config, o, start);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "certislam run: %s\n", e.what());
        return kExitBadInput;
    }
}

const Registrar kRegistrar{"run", "all robots of a configuration in one process (inproc)", RunRun};

}  // namespace
}  // namespace certislam::bin
