// The demo's driver over slam/ pieces: simulator -> mission pipeline -> TSDF -> evaluation;
// the algorithms live in slam/ and certify/, this file only orchestrates and reports.
#include "bin/demo/demo_mission.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <stdexcept>

#include "bin/demo/demo_actors.h"
#include "bin/demo/demo_graph.h"
#include "bin/demo/demo_output.h"
#include "bin/demo/demo_plot.h"
#include "bin/demo/demo_report.h"
#include "certify/pipeline/mission.h"
#include "slam/core/partition.h"
#include "slam/eval/trajectory_metrics.h"
#include "slam/io/g2o_io.h"
#include "slam/io/trajectory_io.h"
#include "slam/mapping/keyframe_fusion.h"
#include "slam/mapping/mesh_io.h"
#include "slam/sim/sim_scenarios.h"
#include "slam/sim/simulator.h"

namespace certislam::bin {
namespace {

using Clock = std::chrono::steady_clock;

double Since(Clock::time_point t) {
    return std::chrono::duration<double>(Clock::now() - t).count();
}

/// The simulated keyframes (clouds included) and the truth, expressed in the team frame.
struct SimulatedTeam {
    std::vector<std::vector<slam::Keyframe>> robots;
    std::vector<std::vector<Eigen::Isometry3d>> truth;  ///< T_world_sensor
    std::vector<slam::Trajectory> ground_truth;         ///< T_team_sensor (robot 0's odom frame)
    std::vector<Eigen::Isometry3d> T_team_odom;         ///< each robot's true odometry frame
    slam::SimStreets streets;                           ///< where the tunnel is
    std::shared_ptr<const slam::MissionGenerator> generator;  ///< makes the clouds
};

slam::SimScenario Scenario(const DemoOptions& options) {
    const std::uint64_t seed =
        options.seed > 0 ? options.seed : slam::ScenarioDefaultSeed(options.scenario);
    auto scenario = slam::MakeScenario(options.scenario, options.robots, seed, options.sequential);
    if (!scenario) throw std::invalid_argument("--scenario " + options.scenario + ": unknown");
    if (options.tunnel_slip >= 0.0) scenario->config.tunnel_slip = options.tunnel_slip;
    return *scenario;
}

/// The team's keyframes and truth; clouds only `with_clouds` (else the actor graph's ingest makes
/// them with team.generator, in parallel).
SimulatedTeam Simulate(const slam::SimScenario& scenario, const DemoOptions& options,
                       bool with_clouds, ProgressBar* bar) {
    SimulatedTeam team;
    team.generator = std::make_shared<const slam::MissionGenerator>(scenario.config);
    const slam::MissionGenerator& generator = *team.generator;
    team.streets = generator.streets();
    const auto keyframes = [&](int r) {
        const int n = generator.num_keyframes(r);
        return options.max_keyframes > 0 ? std::min(n, options.max_keyframes) : n;
    };
    int total = 0, done = 0;
    for (int r = 0; r < generator.num_robots(); ++r) total += keyframes(r);
    const Eigen::Isometry3d T_team_world = generator.T_world_odom(0).inverse();
    for (int r = 0; r < generator.num_robots(); ++r) {
        team.robots.emplace_back();
        team.truth.emplace_back();
        team.ground_truth.emplace_back();
        team.T_team_odom.push_back(T_team_world * generator.T_world_odom(r));
        for (int i = 0; i < keyframes(r); ++i) {
            auto kf = with_clouds ? generator.Generate(r, i)
                                  : slam::SimulatedKeyframe{generator.PoseOnly(r, i),
                                                            generator.T_world_sensor_truth(r, i)};
            team.truth.back().push_back(kf.T_world_sensor_truth);
            team.ground_truth.back().push_back({static_cast<double>(kf.keyframe.stamp_ns) * 1e-9,
                                                T_team_world * kf.T_world_sensor_truth});
            team.robots.back().push_back(std::move(kf.keyframe));
            bar->Update("simulating keyframes", 0.25 * ++done / total);
        }
    }
    return team;
}

/// Odometry alone, started at each robot's true initial pose in the team frame (its best case).
std::vector<slam::Trajectory> OdometryInTeamFrame(const SimulatedTeam& team,
                                                  const std::vector<slam::Trajectory>& odom) {
    auto out = odom;
    for (size_t r = 0; r < out.size(); ++r) {
        for (auto& p : out[r]) p.T_world_body = team.T_team_odom[r] * p.T_world_body;
    }
    return out;
}

/// Bytes of the RBCD exchange: every iteration each robot sends its public poses (r x 4
/// doubles each) to its neighbours.
std::int64_t RbcdBytes(const slam::PoseGraph& graph, int iterations, int rank) {
    const std::int64_t count = slam::CountPublicPoses(graph);
    return count * iterations * rank * 4 * 8;
}

using Methods = std::vector<std::pair<std::string, std::vector<slam::Trajectory>>>;

std::string Fixed(double v) {
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%.1f", v);
    return buf;
}

void Check(bool ok, const std::string& error) {
    if (!ok) throw std::runtime_error(error);
}

void WriteFiles(const DemoOptions& options, const SimulatedTeam& team,
                const certify::MissionResult& mission, const Methods& methods,
                const DemoPlotInput& plot, const slam::TriangleMesh* mesh) {
    namespace fs = std::filesystem;
    fs::create_directories(options.out_dir);
    std::string error;
    const auto path = [&](const std::string& name) {
        return (fs::path(options.out_dir) / name).string();
    };
    for (size_t r = 0; r < team.robots.size(); ++r) {
        const std::string prefix = "robot" + std::to_string(r) + "_";
        Check(slam::WriteTrajectory(path(prefix + "ground_truth.tum"), team.ground_truth[r],
                                    slam::TrajectoryFormat::kTum, &error),
              error);
        for (const auto& [name, traj] : methods) {
            Check(slam::WriteTrajectory(path(prefix + name + ".tum"), traj[r],
                                        slam::TrajectoryFormat::kTum, &error),
                  error);
        }
    }
    Check(slam::WriteG2o(path("joint_graph.g2o"), mission.graph, mission.solution.poses, &error),
          error);
    if (mesh != nullptr) {
        error = slam::WriteMeshPly(path("mesh.ply"), *mesh);
        Check(error.empty(), error);
    }
    Check(WriteDemoPlot(path("trajectories.svg"), plot, &error), error);
}

/// The five methods of Table I (odometry in the team frame at its true start, its best case).
Methods MethodsOf(const SimulatedTeam& team, const certify::MissionResult& mission,
                  const std::vector<slam::Trajectory>& certified) {
    return {
        {"odometry", OdometryInTeamFrame(team, mission.odometry)},
        {"one_time_alignment", mission.one_time_alignment},
        {"local_search", certify::SplitTrajectories(
                             mission.graph, mission.local_search_from_odometry.poses, team.robots)},
        {"local_search_from_alignment",
         certify::SplitTrajectories(mission.graph, mission.local_search_from_alignment.poses,
                                    team.robots)},
        {"certified", certified}};
}

void FillPipelineCertificate(const certify::MissionResult& mission, DemoReport* report) {
    const auto& cert = mission.solution.certificate;
    report->certified = cert.status == certify::CertificateResult::Status::kCertified;
    report->lambda_min = cert.lambda_min;
    report->lambda_min_relative = cert.lambda_min_relative;
    report->verdict = certify::VerdictName(cert.status);
    report->has_bound = cert.has_bound;
    report->lower_bound = cert.lower_bound;
    report->suboptimality_bound = cert.suboptimality_bound;
    report->relative_suboptimality_bound = cert.relative_suboptimality_bound;
    report->cost = mission.solution.cost;
    report->rank = mission.solution.rank;
    report->rbcd_iterations = mission.solution.iterations;
    report->bytes_sent =
        mission.loop_stats.descriptor_bytes_sent + mission.loop_stats.cloud_bytes_sent +
        mission.loop_stats.loop_bytes_sent +
        RbcdBytes(mission.graph, mission.solution.iterations, mission.solution.rank);
    report->bytes_note =
        "serialized sizes of what the protocol sends between robots (descriptors to every peer, "
        "clouds of inter-robot candidates, loop closures, public poses every RBCD iteration), "
        "counted in-process";
}

/// Both local-search runs, judged against the one certified cost of the report.
void FillLocalSearch(const certify::MissionResult& mission, const DemoPlotInput& plot,
                     DemoReport* report) {
    report->local_search =
        LocalSearchReport("odometry (each robot's odometry frame taken as the team frame)",
                          mission.local_search_from_odometry, report->cost, plot.methods[2].rmse);
    report->local_search_aligned =
        LocalSearchReport("the one-time alignment (DiSCo-style first-encounter frames)",
                          mission.local_search_from_alignment, report->cost, plot.methods[3].rmse);
}

void FillLoops(const certify::MissionResult& mission, DemoReport* report) {
    report->inter_robot_loops = 0;
    report->intra_robot_loops = 0;
    for (const auto& loop : mission.loops) {
        ++(loop.inter_robot() ? report->inter_robot_loops : report->intra_robot_loops);
    }
    report->candidates = mission.loop_stats.candidates;
    report->loop_source = mission.loops.empty() || !mission.loops.front().from_ground_truth
                              ? "front end (Scan Context + registration + PCM)"
                              : "GROUND TRUTH with noise (fallback)";
    report->warnings.insert(report->warnings.end(), mission.warnings.begin(),
                            mission.warnings.end());
}

/// Table I's rows and the plot: each method scored under its own joint alignment of the team.
DemoPlotInput ScoreMethods(const SimulatedTeam& team, const Methods& methods, DemoReport* report) {
    DemoPlotInput plot{"certislam demo (" + report->scenario +
                           "): " + std::to_string(team.robots.size()) +
                           " robots, top-down (x-y, team frame), joint SE(3) alignment",
                       team.ground_truth,
                       {}};
    const char* colours[] = {"#7f7f7f", "#ff7f0e", "#9467bd", "#8c564b", "#2ca02c"};
    const char* names[] = {"odometry", "one-time alignment", "local search (LM) from odometry",
                           "local search (LM) from alignment", "certified RBCD"};
    for (size_t m = 0; m < methods.size(); ++m) {
        slam::AlignedTeam scored = slam::AlignTeam(team.ground_truth, methods[m].second);
        plot.methods.push_back({names[m], colours[m], std::move(scored.aligned), scored.ate_rmse,
                                m == 2 || m == 3 ? 4.0 : 1.6});  // wide: may hide certified
    }
    const auto gain = [](double baseline, double ours) {
        return baseline > 0.0 ? 100.0 * (baseline - ours) / baseline : 0.0;
    };
    for (size_t r = 0; r < team.robots.size(); ++r) {
        DemoRobotRow row;
        row.id = static_cast<int>(r);
        row.keyframes = static_cast<int>(team.robots[r].size());
        row.odometry = plot.methods[0].rmse[r];
        row.one_time_alignment = plot.methods[1].rmse[r];
        row.local_search = plot.methods[2].rmse[r];
        row.local_search_aligned = plot.methods[3].rmse[r];
        row.certified = plot.methods[4].rmse[r];
        row.improvement_over_alignment_pct = gain(row.one_time_alignment, row.certified);
        row.improvement_over_odometry_pct = gain(row.odometry, row.certified);
        if (row.certified > row.odometry) {
            report->warnings.push_back("robot " + std::to_string(r) + "'s certified RMSE " +
                                       Fixed(row.certified) + " m is worse than its odometry's");
        }
        report->robots.push_back(row);
    }
    return plot;
}

std::string PipelineText(bool actors) {
    if (!actors) {
        return "Table I from the slam/certify mission pipeline called directly in one thread "
               "(loops, joint graph, baselines, certified RBCD); bytes_sent is counted from "
               "serialized sizes, not measured on sockets";
    }
    return "one front end: the actor graph (ingest, descriptor, loop matcher with PCM, RBCD "
           "solver, certifier per robot, every robot in this process over inproc) gives the "
           "loops, certified RBCD, the certificate and bytes_sent; the baselines (odometry, "
           "one-time alignment, local search from odometry and from the alignment, each with "
           "its own certificate) run on the team graph the actors solved (their edges, same "
           "weights), so every row of Table I is on one graph";
}

std::string MissionText(const slam::SimScenario& scenario, const DemoOptions& options) {
    return scenario.name + ": " + std::to_string(scenario.config.num_robots) + " robots " +
           (options.sequential ? "driving one after another" : "driving at once") + "; " +
           scenario.description + " (seed " + std::to_string(scenario.config.seed) +
           ", tunnel slip " + Fixed(100.0 * scenario.config.tunnel_slip) + " %)";
}

/// The certified row from the actor graph, the baselines on the graph it solved.
certify::MissionResult ActorPath(const DemoOptions& options, const SimulatedTeam& team,
                                 const certify::MissionConfig& config, ProgressBar* bar,
                                 ActorMissionResult* run, DemoReport* report) {
    const std::shared_ptr<const slam::MissionGenerator> generator = team.generator;
    certify::MissionResult mission;
    // The baselines need only the finished graph: they run while robot 0's mapper meshes (the
    // bar is theirs meanwhile).
    *run = RunThroughActors(
        team.robots, options.actors_timeout_s, options.voxel_m, config.loops.query_stride,
        options.distributed_certificate,
        [&](const std::string& stage, double f) { bar->Update(stage, 0.25 + 0.5 * f); },
        [generator](int robot, int index) {
            return generator->Generate(robot, index).keyframe.cloud;
        },
        [&](const ActorMissionResult& graph) {
            mission = BaselinesOnActorGraph(
                team.robots, graph, config,
                [&](const std::string& stage, double f) { bar->Update(stage, 0.75 + 0.15 * f); });
        });
    report->timings["actor_graph"] = run->seconds;
    report->timings["actor_graph_mesh"] = run->mesh_seconds;
    report->timings["actor_graph_stop"] = run->stop_seconds;
    FillFromActors(*run, &mission, report);
    return mission;
}

}  // namespace

DemoReport RunDemoMission(const DemoOptions& options) {
    const auto start = Clock::now();
    DemoReport report;
    ProgressBar bar(!options.quiet);
    const slam::SimScenario scenario = Scenario(options);
    const bool actors = options.actors && !options.ground_truth_loops;
    const SimulatedTeam team = Simulate(scenario, options, /*with_clouds=*/!actors, &bar);
    report.scenario = scenario.name;
    report.mission = MissionText(scenario, options);
    report.timings["simulation"] = Since(start);

    certify::MissionConfig config;
    config.loops.query_stride = scenario.loop_query_stride;
    if (options.ground_truth_loops) config.loops.source = slam::LoopSource::kGroundTruth;
    report.pipeline = PipelineText(actors);
    report.certified_source = actors ? "actor graph" : "pipeline";
    std::optional<ActorMissionResult> run;
    certify::MissionResult mission;
    if (actors) {
        run.emplace();
        mission = ActorPath(options, team, config, &bar, &*run, &report);
    } else {
        mission = certify::RunMission(
            team.robots, team.truth, config,
            [&](const std::string& stage, double f) { bar.Update(stage, 0.25 + 0.6 * f); });
        FillPipelineCertificate(mission, &report);
        report.timings["front_end"] = mission.front_end_seconds;
        report.timings["rbcd_and_certificate"] = mission.solution.seconds;
    }
    report.timings["baselines_and_local_search"] = mission.back_end_seconds;
    const Methods methods = MethodsOf(team, mission, mission.certified);
    const DemoPlotInput plot = ScoreMethods(team, methods, &report);
    FillLocalSearch(mission, plot, &report);
    FillLoops(mission, &report);

    slam::TriangleMesh mesh;
    const auto map_start = Clock::now();
    if (run) {
        mesh = std::move(run->mesh);  // robot 0's TSDF mapper actor: every robot's submaps
    } else if (options.voxel_m > 0) {
        mesh = slam::FuseKeyframes(team.robots, mission.certified, options.voxel_m, [&](double f) {
            bar.Update("fusing TSDF map", 0.85 + 0.1 * f);
        });
    }
    report.timings["tsdf_mesh"] = Since(map_start);
    if (!options.out_dir.empty()) {
        bar.Update("writing files", 0.97);
        const auto files_start = Clock::now();
        WriteFiles(options, team, mission, methods, plot, options.voxel_m > 0 ? &mesh : nullptr);
        report.timings["files"] = Since(files_start);
        report.out_dir = options.out_dir;
    }
    report.seconds = Since(start);
    int keyframes = 0;
    for (const auto& r : report.robots) keyframes += r.keyframes;
    report.keyframes_per_second = keyframes / report.seconds;
    report.ok = true;
    bar.Update("done", 1.0);
    bar.Done();
    if (!options.out_dir.empty()) {
        std::ofstream(std::filesystem::path(options.out_dir) / "report.json")
            << DemoReportJson(report).dump(2) << "\n";
    }
    return report;
}

}  // namespace certislam::bin
