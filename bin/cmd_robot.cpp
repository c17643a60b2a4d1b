// `certislam robot CONFIG --id K [--out DIR] [--json]`: one robot's actor graph in this process;
// its peers are other processes reached over tcp, with CURVE when the configuration names keys
// (distributed multi-host mode). With mapping on, its TSDF mapper's mesh goes to
// DIR/robot<K>.mesh.ply (the anchor's holds every robot's submaps; see mapping.team_map).
#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <thread>

#include "bin/command.h"
#include "bin/config/team_config.h"
#include "bin/progress.h"
#include "bin/robot_command.h"
#include "bin/stop_within.h"

namespace certislam::bin {
namespace {

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

/// A keyframe robot: every actor of its node, fed by its source; outputs under --out.
int RunKeyframeRobot(const RobotCommandOptions& o, zmq::context_t& context,
                     const actors::TeamWiring& wiring, const TeamConfig& config) {
    const auto start = std::chrono::steady_clock::now();
    const int id = o.id;
    CheckActorSettings(config);
    const TeamSource source(config.source, config.robots);
    const actors::RobotNodeConfig node_config = NodeConfigFor(config, id);
    actors::RobotNode node(context, wiring, source.For(id), node_config);
    node.Start();
    const auto states = [&] { return std::vector<actors::SolverSnapshot>{node.Snapshot()}; };
    Progress progress(
        "certislam robot " + std::to_string(id), MakeProgressConfig(o.progress_s, o.snapshot_s),
        [&] {
            if (o.out_dir.empty()) return;
            const std::string now = WriteTeamOutputs(
                o.out_dir, {id}, states(), source,
                actors::SummariseNodes<actors::RobotNode>({&node}),
                std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(),
                "");
            std::ofstream(o.out_dir + "/robot" + std::to_string(id) + ".report.json")
                << now << "\n";
        });
    const bool done =
        WaitWithProgress([&] { return node.Done(); }, start, o.timeout_s, &progress, states);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const auto snapshot = node.Snapshot();
    const actors::PoseGraphTeamResult counters = actors::SummariseNodes<actors::RobotNode>({&node});
    // After the deadline the mapper is not waited for: no mesh then.
    const nlohmann::json mesh = done ? WriteRobotMesh(node, node_config, id, o.out_dir) : nullptr;
    node.RequestStop();
    auto report = nlohmann::json::parse(
        WriteTeamOutputs(o.out_dir, {id}, {snapshot}, source, counters, seconds, ""));
    AddActorCounters(node, counters.bytes_by_actor, &report);
    if (!mesh.is_null()) report["mesh"] = mesh;
    const std::string text = report.dump(2);
    if (!o.out_dir.empty()) {
        std::ofstream(o.out_dir + "/robot" + std::to_string(id) + ".report.json") << text << "\n";
    }
    if (o.json) {
        std::printf("%s\n", text.c_str());
    } else {
        std::printf("%s%s\n", TeamReportText(text).c_str(),
                    done ? "done: certified" : "not certified before the timeout");
    }
    const int code = done ? kExitDone : kExitNotCertified;
    StopWithin([&] { node.Stop(); }, kStopGrace, code);
    return code;
}

int RunRobot(int argc, char** argv) {
    CLI::App app{"One robot of a configuration; peers over tcp (CURVE with keys)"};
    app.name("certislam robot");
    RobotCommandOptions o;
    AddRobotCommandOptions(app, &o);
    CLI11_PARSE(app, argc, argv);
    return RunRobotCommand(
        o, "certislam robot",
        [&](zmq::context_t& context, const actors::TeamWiring& wiring, const TeamConfig& config) {
            return RunKeyframeRobot(o, context, wiring, config);
        });
}

const Registrar kRegistrar{"robot", "one robot of a configuration; peers over tcp with CURVE",
                           RunRobot};

}  // namespace
}  // namespace certislam::bin
