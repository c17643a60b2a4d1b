// A pose-graph team in one process: nodes over inproc, watched until done.
#include "actors/pose_graph_team.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <thread>

#include "transport/context.h"

namespace certislam::actors {
namespace {

constexpr std::chrono::milliseconds kWatchPeriod{20};

}  // namespace

PoseGraphTeamResult SummariseNodes(const std::vector<const PoseGraphNode*>& nodes) {
    PoseGraphTeamResult out;
    bool sync = true;
    for (const auto& node : nodes) {
        const SolverSnapshot s = node->Snapshot();
        out.iterations_by_robot[node->robot()] = s.steps;
        out.iterations = std::max(out.iterations, s.steps);
        for (const auto& [actor, bytes] : node->BytesSentToPeersByActor()) {
            out.bytes_by_actor[actor] += bytes;
            out.bytes_by_robot[node->robot()] += bytes;
            out.bytes_between_robots += bytes;
        }
        out.escapes += node->Certifier().Escapes();
        out.rejected_proposals += s.rejected_proposals;
        for (const auto& pose : s.trajectory) {
            const Eigen::Isometry3d& T = pose.T_world_body;
            out.out_of_plane_m = std::max(out.out_of_plane_m, std::abs(T.translation().z()));
            const double cos_tilt = std::clamp(T.linear()(2, 2), -1.0, 1.0);
            out.out_of_plane_rad = std::max(out.out_of_plane_rad, std::acos(cos_tilt));
        }
        sync = sync && s.rounds_converged && !s.rounds_gave_up;
    }
    out.solver_mode = sync ? "synchronous" : "asynchronous";
    const PoseGraphNode& anchor = *nodes.front();
    const SolverSnapshot s = anchor.Snapshot();
    out.report = s.report;
    out.rank = s.rank;
    out.restarts = s.restarts;
    out.overlap_ends = s.overlap_ends;
    out.fallbacks = anchor.Certifier().Fallbacks();
    out.certificate_rounds = anchor.Certifier().Rounds();
    out.lanczos_steps = anchor.Certifier().LanczosSteps();
    out.certificate_seconds = anchor.Certifier().RoundSeconds();
    return out;
}

PoseGraphTeamResult RunPoseGraphTeam(const std::vector<slam::RobotGraph>& graphs,
                                     const PoseGraphNodeConfig& config,
                                     std::chrono::duration<double> timeout) {
    std::vector<int> robots;
    robots.reserve(graphs.size());
    for (const auto& g : graphs) robots.push_back(g.robot);
    zmq::context_t context;
    transport::ReserveSockets(context, InprocTeamSockets(static_cast<int>(robots.size()), false));
    std::vector<std::unique_ptr<PoseGraphNode>> nodes;
    nodes.reserve(graphs.size());
    for (const auto& g : graphs) {
        nodes.push_back(
            std::make_unique<PoseGraphNode>(context, InprocWiring(g.robot, robots), g, config));
    }
    const auto start = std::chrono::steady_clock::now();
    for (auto& node : nodes) node->Start();
    bool done = false;
    const auto since = [&] {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    };
    double converged = -1.0, certified = -1.0;
    while (!done && std::chrono::steady_clock::now() - start < timeout) {
        std::this_thread::sleep_for(kWatchPeriod);
        done = std::all_of(nodes.begin(), nodes.end(), [](const auto& n) { return n->Done(); });
        if (converged < 0.0 && std::all_of(nodes.begin(), nodes.end(), [](const auto& n) {
                return n->Snapshot().rounds_converged;
            })) {
            converged = since();
        }
        if (certified < 0.0) {  // a snapshot copies the trajectory: taken only until first seen
            const auto report = nodes.front()->Snapshot().report;
            if (report && report->verdict() == v1::CERTIFICATE_VERDICT_CERTIFIED)
                certified = since();
        }
    }
    const double seconds = since();
    std::vector<const PoseGraphNode*> views;
    views.reserve(nodes.size());
    for (const auto& node : nodes) views.push_back(node.get());
    PoseGraphTeamResult out = SummariseNodes(views);
    out.done = done;
    out.seconds = seconds;
    out.seconds_to_converged = converged;
    out.seconds_to_certified = certified;
    out.cost_offset = slam::CostOffset(graphs);
    for (auto& node : nodes) node->Stop();
    return out;
}

}  // namespace certislam::actors
