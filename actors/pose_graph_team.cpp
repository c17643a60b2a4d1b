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
