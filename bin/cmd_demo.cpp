// `certislam demo`: the simulated N-robot mission end to end, then the paper's Table I
// (position RMSE of odometry, one-time alignment, local search, certified RBCD) and the files.
#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "bin/command.h"
#include "bin/demo/demo_mission.h"
#include "slam/sim/sim_scenarios.h"

namespace certislam::bin {
namespace {

void PrintRows(const DemoReport& report) {
    std::printf("\nTable I (%s): trajectory position RMSE (m), %d robots, joint SE(3) alignment\n",
                report.scenario.c_str(), static_cast<int>(report.robots.size()));
    std::printf("%-5s %9s %9s %9s %12s %12s %9s %11s %11s\n", "robot", "keyframes", "odometry",
                "one-time", "LS from OTA", "LS from odom", "certified", "vs OTA %", "vs odom %");
    for (const auto& r : report.robots) {
        std::printf("%-5d %9d %9.3f %9.3f %12.3f %12.3f %9.3f %11.1f %11.1f\n", r.id, r.keyframes,
                    r.odometry, r.one_time_alignment, r.local_search_aligned, r.local_search,
                    r.certified, r.improvement_over_alignment_pct, r.improvement_over_odometry_pct);
    }
    std::printf(
        "(OTA: DiSCo-style one-time alignment; LS: local search, Levenberg-Marquardt, "
        "polished and certified on its own)\n");
}

void PrintTable(const DemoReport& report) {
    PrintRows(report);
    std::printf("\ncertified RBCD: certificate %s   lambda_min %.3e   ", report.verdict.c_str(),
                report.lambda_min);
    if (report.has_bound) {
        std::printf("suboptimality bound %.3e (relative %.3e)\n", report.suboptimality_bound,
                    report.relative_suboptimality_bound);
    } else {
        std::printf("suboptimality bound: none proven\n");
    }
    std::printf("certified RBCD: cost f = %.6g, rank %d, %d RBCD iterations\n", report.cost,
                report.rank, report.rbcd_iterations);
    for (const DemoLocalSearch* ls : {&report.local_search_aligned, &report.local_search}) {
        std::printf(
            "local search (LM from %s): %s in %d iterations, cost %.6g (%+.3g vs certified), "
            "certificate: %s (lambda_min %.3e)\n",
            ls->start.c_str(), ls->status.c_str(), ls->iterations, ls->cost, ls->gap,
            ls->verdict.c_str(), ls->lambda_min);
    }
    std::printf(
        "loops: %d inter-robot, %d intra-robot   bytes sent %lld   %.2f s (%.1f keyframes/s)\n",
        report.inter_robot_loops, report.intra_robot_loops,
        static_cast<long long>(report.bytes_sent), report.seconds, report.keyframes_per_second);
    std::printf("mission: %s\n", report.mission.c_str());
    std::printf("certified row and certificate from: %s\n", report.certified_source.c_str());
    std::printf("pipeline: %s\n", report.pipeline.c_str());
    if (!report.actor_graph.is_null()) {
        std::printf("actor graph over inproc: %s\n", report.actor_graph.dump().c_str());
    }
    for (const auto& w : report.warnings) std::printf("WARNING: %s\n", w.c_str());
    if (!report.out_dir.empty()) std::printf("files in %s\n", report.out_dir.c_str());
}

int RunDemo(int argc, char** argv) {
    DemoOptions options;
    CLI::App app{"Simulated multi-robot mission end to end: Table I and files in --out."};
    app.add_option("--scenario", options.scenario,
                   "simulated mission: tunnel-rendezvous (default), city, large-drift, swarm")
        ->check(CLI::IsMember(slam::ScenarioNames()));
    app.add_option("--robots", options.robots, "number of robots (default: the scenario's)")
        ->check(CLI::Range(1, 16));
    app.add_option("--out", options.out_dir, "output folder (trajectories, graph, mesh, plot)");
    app.add_option("--seed", options.seed, "simulator seed (default, or 0: the scenario's)");
    app.add_option("--keyframes", options.max_keyframes,
                   "keyframes per robot at most (0: whole routes; small values for quick tests)")
        ->check(CLI::NonNegativeNumber);
    app.add_option("--voxel", options.voxel_m, "TSDF voxel size of the fused mesh, m (0: none)");
    app.add_flag("--ground-truth-loops", options.ground_truth_loops,
                 "use ground-truth loop closures with noise instead of the front end (said so)");
    app.add_option("--tunnel-slip", options.tunnel_slip,
                   "fraction of motion odometry misses inside the tunnel (degeneracy model; "
                   "default: the scenario's)")
        ->check(CLI::Range(0.0, 0.9));
    app.add_flag("!--concurrent", options.sequential,
                 "robots drive at the same time (default: one after another, as in the paper)");
    bool pipeline_only = false, actors_flag = false;
    app.add_flag("--pipeline", pipeline_only,
                 "certified row from the slam/certify pipeline called directly, no actor graph");
    app.add_flag("--actors", actors_flag, "the default (kept for older scripts): actor graph");
    app.add_option("--actors-timeout", options.actors_timeout_s,
                   "seconds the actor graph gets to be certified and quiet")
        ->check(CLI::PositiveNumber);
    std::string certificate = "distributed";
    app.add_option("--certificate", certificate,
                   "distributed (every robot its rows of S, LOBPCG over the sockets; default) or "
                   "centralised (the anchor checks the joint certificate alone; faster)")
        ->check(CLI::IsMember({"distributed", "centralised"}));
    app.add_flag("--quiet", options.quiet, "no progress bar");
    app.add_flag("--json", options.json, "print the report as JSON");
    CLI11_PARSE(app, argc, argv);
    options.actors = !pipeline_only;
    options.distributed_certificate = certificate == "distributed";
    const DemoReport report = RunDemoMission(options);
    if (options.json) {
        std::printf("%s\n", DemoReportJson(report).dump(2).c_str());
    } else {
        PrintTable(report);
    }
    return report.ok ? 0 : 1;
}

const Registrar kRegistrar{"demo", "simulated multi-robot mission end to end (Table I + files)",
                           RunDemo};

}  // namespace
}  // namespace certislam::bin
