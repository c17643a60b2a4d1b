// The distributed solve: split, run the team of actors, report.
#include "bin/solve_distributed.h"

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
            for (const char* key :
                 {"lower_bound", "suboptimality_bound", "relative_suboptimality_bound"}) {
                j->erase(key);
            }
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
    if (o.overlap >= 0) config.solver.rounds.overlap_depth = o.overlap;
    if (o.finish_after >= 0) config.solver.finish_after_rounds = o.finish_after;
    if (o.max_rounds > 0) config.solver.rounds.max_rounds = o.max_rounds;
    config.certifier.lanczos.method = o.eigensolver == "lanczos"
                                          ? certify::LanczosSettings::Method::kLanczos
                                          : certify::LanczosSettings::Method::kLobpcg;
    const actors::PoseGraphTeamResult result =
        actors::RunPoseGraphTeam(graphs, config, std::chrono::duration<double>(o.timeout_s));
    nlohmann::json j = TeamResultJson(result, static_cast<int>(graphs.size()));
    j["eigensolver"] = o.eigensolver;
    j["overlap"] = config.solver.rounds.overlap_depth;
    j["finish_after_rounds"] = config.solver.finish_after_rounds;
    return PrintDistributedReport(&j, result, graph, o);
}

}  // namespace certislam::bin
