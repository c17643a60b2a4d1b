// The distributed solve: split, run the team of actors, report.
#include "bin/solve_distributed.h"

#include <sys/resource.h>

#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "bin/command.h"
#include "bin/solve_processes.h"
#include "bin/verdict.h"
#include "slam/core/graph_split.h"

namespace certislam::bin {
namespace {

constexpr double kPlanarTolerance = 1e-6;  ///< metres and radians off the plane z = 0

double PeakRssMb() {
    rusage usage{};
    getrusage(RUSAGE_SELF, &usage);
    return static_cast<double>(usage.ru_maxrss) / 1024.0;  // KiB on Linux
}

void PrintText(const nlohmann::json& j) {
    std::printf("poses %d   edges %d   robots %d   path distributed (%s)\n", j["poses"].get<int>(),
                j["edges"].get<int>(), j["robots"].get<int>(),
                j["transport"].get<std::string>().c_str());
    std::printf("objective %.10g   verdict: %s\n", j["cost"].get<double>(),
                j["verdict"].get<std::string>().c_str());
    std::printf(
        "team iterations %llu (%s)   certificate rounds %d (central fallbacks %d)   "
        "eigen-solver exchanges %llu\n",
        j["iterations"].get<unsigned long long>(), j["solver_mode"].get<std::string>().c_str(),
        j["certificate_rounds"].get<int>(), j["central_fallbacks"].get<int>(),
        j["lanczos_steps"].get<unsigned long long>());
    std::printf("bytes between robots %llu   %.3f s   peak RSS %.1f MB\n",
                j["bytes_between_robots"]["total"].get<unsigned long long>(),
                j["seconds"].get<double>(), j["peak_rss_mb"].get<double>());
}

}  // namespace

nlohmann::json TeamResultJson(const actors::PoseGraphTeamResult& r, int robots,
                              const std::string& transport) {
    const v1::CertificateReport report = r.report.value_or(v1::CertificateReport{});
    const bool certified = r.done && report.verdict() == v1::CERTIFICATE_VERDICT_CERTIFIED;
    // The file's cost: the team's plus the constant of its merged parallel edges (none heard: 0).
    const double cost = r.report ? report.objective() + r.cost_offset : 0.0;
    nlohmann::json j = {{"schema_version", kSchemaVersion},
                        {"method", "rbcd"},
                        {"path", "distributed"},
                        {"transport", transport},
                        {"objective", cost},
                        {"cost", cost},
                        {"cost_offset", r.cost_offset},
                        {"certified", certified},
                        {"verdict", VerdictName(report.verdict())},
                        {"certificate_path", CertificatePathName(report.path())},
                        {"rank", r.rank},
                        {"iterations", r.iterations},
                        {"seconds", r.seconds},
                        {"seconds_to_converged", r.seconds_to_converged},
                        {"seconds_to_certified", r.seconds_to_certified},
                        {"certificate_rounds", r.certificate_rounds},
                        {"lanczos_steps", r.lanczos_steps},
                        {"certificate_seconds", r.certificate_seconds},
                        {"escapes", r.escapes},
                        {"solver_mode", r.solver_mode},
                        {"restarts", r.restarts},
                        {"central_fallbacks", r.fallbacks},
                        {"bytes_between_robots",
                         {{"total", r.bytes_between_robots}, {"by_actor", r.bytes_by_actor}}},
                        {"peak_rss_mb", PeakRssMb()},
                        {"robots", robots}};
    nlohmann::json by_robot = nlohmann::json::object(), steps = nlohmann::json::object();
    for (const auto& [robot, bytes] : r.bytes_by_robot) by_robot[std::to_string(robot)] = bytes;
    for (const auto& [robot, n] : r.iterations_by_robot) steps[std::to_string(robot)] = n;
    j["bytes_between_robots"]["by_robot"] = by_robot;
    j["iterations_by_robot"] = steps;
    if (r.report) {
        j["lambda_min"] = report.lambda_min();
        // Only a bound the report carries (a zero field is an absent one, not a proof of f*).
        if (certified && report.suboptimality_bound() > 0.0) {
            j["suboptimality_bound"] = report.suboptimality_bound();
        }
    }
    if (!r.done) j["reason"] = "not certified before the timeout";
    return j;
}

int PrintDistributedReport(nlohmann::json* j, const actors::PoseGraphTeamResult& result,
                           const slam::PoseGraph& graph, const DistributedSolveOptions& o) {
    if (graph.d == 2) {
        // Solved as its lift into SE(3): the lifted optimum is the planar one only when planar.
        (*j)["lifted_from_planar"] = true;
        (*j)["out_of_plane"] = {{"m", result.out_of_plane_m}, {"rad", result.out_of_plane_rad}};
        if ((*j)["certified"].get<bool>() &&
            std::max(result.out_of_plane_m, result.out_of_plane_rad) > kPlanarTolerance) {
            (*j)["certified"] = false;
            (*j)["verdict"] = "inconclusive";
            (*j)["reason"] = "the certified optimum of the planar graph's lift leaves the plane";
            j->erase("suboptimality_bound");
        }
    }
    (*j)["file"] = o.file;
    (*j)["poses"] = graph.n;
    (*j)["edges"] = static_cast<int>(graph.edges.size());
    (*j)["quiet_seconds"] = o.quiet_s;
    if (o.json) {
        std::printf("%s\n", j->dump(2).c_str());
    } else {
        PrintText(*j);
    }
    return (*j)["certified"].get<bool>() ? kExitDone : kExitNotCertified;
}

int RunDistributedSolve(const slam::PoseGraph& graph, const DistributedSolveOptions& o) {
    std::vector<slam::RobotGraph> graphs;
    try {
        const slam::Partition partition = o.robots > 0
                                              ? slam::ContiguousPartition(graph.n, o.robots)
                                              : slam::PartitionFromIds(graph);
        graphs = slam::SplitGraph(graph, partition);
        if (o.transport != "inproc") return RunProcessSolve(graph, partition, o);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "certislam solve: error: %s: --distributed: %s\n", o.file.c_str(),
                     e.what());
        return kExitBadInput;
    }
    actors::PoseGraphNodeConfig config;
    config.quiet = std::chrono::milliseconds(std::llround(o.quiet_s * 1000.0));
    config.certifier.certificate.max_relative_bound = o.max_relative_bound;
    config.certifier.lanczos.method = o.eigensolver == "lanczos"
                                          ? certify::LanczosSettings::Method::kLanczos
                                          : certify::LanczosSettings::Method::kLobpcg;
    const actors::PoseGraphTeamResult result =
        actors::RunPoseGraphTeam(graphs, config, std::chrono::duration<double>(o.timeout_s));
    nlohmann::json j = TeamResultJson(result, static_cast<int>(graphs.size()));
    j["eigensolver"] = o.eigensolver;
    return PrintDistributedReport(&j, result, graph, o);
}

}  // namespace certislam::bin
