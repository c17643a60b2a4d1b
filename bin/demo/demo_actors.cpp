// One RobotNode per robot, inproc wiring, keyframes served from memory, poll until done.
#include "bin/demo/demo_actors.h"

#include <algorithm>
#include <chrono>
#include <future>
#include <memory>
#include <thread>
#include <zmq.hpp>

#include "actors/robot_node.h"
#include "actors/wiring.h"
#include "bin/verdict.h"
#include "transport/context.h"

namespace certislam::bin {
namespace {

/// deploy/configs/sim2.json's settings, but every `query_stride`-th keyframe of a robot queries
/// (the scenario's) with at most two candidates per robot, and registration as the pipeline's
/// loop stage sets it (0.4 m voxels).
actors::RobotNodeConfig DemoConfig(double voxel_m, int query_stride, bool distributed_certificate) {
    actors::RobotNodeConfig config;
    config.mapping = voxel_m > 0;
    if (config.mapping) config.mapper.map.tsdf.voxel_size_m = voxel_m;
    config.solver.solver.rank = 5;
    config.solver.solver.rbcd.rel_grad_tol = 1e-9;
    config.solver.synchronous = true;  // rounds once the graph is final (no robot restarts here)
    // The certifiers run the distributed check (every robot its rows of S; the default), the
    // anchor's centralised check only as the fallback of a silent round; false: the anchor's
    // centralised check alone (`certislam demo --certificate centralised`).
    config.certifier.distributed = distributed_certificate;
    config.matcher.query_stride = query_stride;
    config.matcher.max_sc_distance = 0.2;
    // The two most similar places per keyframe and robot: in a tunnel one keyframe resembles a
    // whole stretch of the other robot's, and each candidate costs a GICP.
    config.matcher.max_candidates_per_query = 2;
    config.matcher.registration.voxel_m = 0.4;
    // The mesh waits two publish periods for the last re-anchorings: 100 ms, not the default 500.
    config.mapper.publish_period = std::chrono::milliseconds(100);
    config.matcher.registration.max_correspondence_m = 2.5 * 0.4;
    config.matcher.registration.inlier_distance_m =
        std::max(config.matcher.registration.inlier_distance_m, 0.4);
    return config;
}

void Collect(const std::vector<std::unique_ptr<actors::RobotNode>>& nodes,
             ActorMissionResult* result) {
    int loop_ends = 0;
    for (const auto& node : nodes) {
        const actors::SolverSnapshot snapshot = node->Snapshot();
        result->trajectory.push_back(snapshot.trajectory);
        result->anchor.push_back(snapshot.anchor);
        result->inter_robot_loops.push_back(snapshot.inter_robot_loops);
        loop_ends += snapshot.inter_robot_loops;  // each such loop touches two robots
        result->loops_found.push_back(node->LoopsFound());
        const actors::LoopMatcherActor& matcher = node->Matcher();
        result->registrations.push_back(matcher.Verified() + matcher.Rejected());
        result->loops_verified.push_back(matcher.Verified());
        result->solver_steps.push_back(snapshot.steps);
        result->edges.insert(result->edges.end(), snapshot.edges.begin(), snapshot.edges.end());
        result->bytes_sent += node->BytesSentToPeers();
        for (const auto& [actor, bytes] : node->BytesSentToPeersByActor()) {
            result->bytes_by_actor[actor] += bytes;
        }
        if (!snapshot.report) {
            result->certified = false;
            continue;
        }
        const auto& report = *snapshot.report;
        const bool certified = report.verdict() == v1::CERTIFICATE_VERDICT_CERTIFIED;
        result->certified = (node == nodes.front() || result->certified) && certified;
        if (node == nodes.front()) {  // the anchor's certifier reports to every robot
            result->verdict = VerdictName(report.verdict());
            result->certificate_path = CertificatePathName(report.path());
            result->lambda_min = report.lambda_min();
            // Only a bound the certificate proved (S + eta D PSD on the report's graph).
            result->has_bound = report.has_bound();
            result->suboptimality_bound = result->has_bound ? report.suboptimality_bound() : 0.0;
            result->lower_bound = result->has_bound ? report.lower_bound() : 0.0;
            result->relative_suboptimality_bound =
                result->has_bound ? report.relative_suboptimality_bound() : 0.0;
            result->cost = report.objective();
            result->rank = static_cast<int>(report.rank_r());
        }
    }
    result->team_inter_robot_loops = loop_ends / 2;
    const actors::CertifierActor& anchor = nodes.front()->Certifier();
    result->certificate_rounds = anchor.Rounds();
    result->saddle_escapes = anchor.Escapes();
    result->lanczos_steps = anchor.LanczosSteps();
    result->settled_skips = anchor.SettledSkips();
}

struct Poll {
    bool done = true;                      // every node done
    bool final = true;                     // every robot's graph final
    size_t solved = 0;                     // poses the solvers hold
    std::vector<slam::LoopClosure> edges;  // the team graph, as Collect gathers it
};

Poll PollNodes(const std::vector<std::unique_ptr<actors::RobotNode>>& nodes) {
    Poll poll;
    for (const auto& node : nodes) {
        poll.done = poll.done && node->Done();
        const actors::SolverSnapshot snapshot = node->Snapshot();
        poll.solved += static_cast<size_t>(snapshot.num_poses);
        poll.final = poll.final && snapshot.final;
        poll.edges.insert(poll.edges.end(), snapshot.edges.begin(), snapshot.edges.end());
    }
    return poll;
}

bool SameEdges(const std::vector<slam::LoopClosure>& a, const std::vector<slam::LoopClosure>& b) {
    return std::equal(a.begin(), a.end(), b.begin(), b.end(), [](const auto& x, const auto& y) {
        return x.a == y.a && x.b == y.b && x.T_a_b.matrix() == y.T_a_b.matrix() &&
               x.kappa == y.kappa && x.tau == y.tau;
    });
}

}  // namespace

ActorMissionResult RunThroughActors(const std::vector<std::vector<slam::Keyframe>>& robots,
                                    double timeout_s, double voxel_m, int query_stride,
                                    bool distributed_certificate, const ActorProgress& progress,
                                    const CloudMaker& make_cloud,
                                    const WhileMeshing& while_meshing) {
    using Clock = std::chrono::steady_clock;
    const auto start = Clock::now();
    std::vector<int> ids;
    size_t total = 0;
    for (size_t r = 0; r < robots.size(); ++r) {
        ids.push_back(static_cast<int>(r));
        total += robots[r].size();
    }
    const actors::RobotNodeConfig config =
        DemoConfig(voxel_m, query_stride, distributed_certificate);
    zmq::context_t context;
    transport::ReserveSockets(context,
                              actors::InprocTeamSockets(static_cast<int>(ids.size()), true));
    std::vector<std::unique_ptr<actors::RobotNode>> nodes;
    for (int r : ids) {
        auto next = std::make_shared<size_t>(0);
        const auto* keyframes = &robots[static_cast<size_t>(r)];
        actors::KeyframeSource source = [keyframes, next,
                                         make_cloud]() -> std::optional<slam::Keyframe> {
            if (*next >= keyframes->size()) return std::nullopt;
            slam::Keyframe kf = (*keyframes)[(*next)++];
            if (!kf.cloud && make_cloud) kf.cloud = make_cloud(kf.robot, kf.index);
            return kf;
        };
        nodes.push_back(std::make_unique<actors::RobotNode>(context, actors::InprocWiring(r, ids),
                                                            std::move(source), config));
    }
    for (auto& node : nodes) node->Start();
    ActorMissionResult result;
    // The side work starts on the final graph's edges (the robots then only solve and certify
    // it) and owns the progress bar from then on.
    ActorMissionResult final_graph;
    std::future<void> side;
    const auto deadline = start + std::chrono::duration<double>(timeout_s);
    while (!result.done && Clock::now() < deadline) {
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
        Poll now = PollNodes(nodes);
        result.done = now.done;
        if (while_meshing && now.final && !side.valid()) {
            final_graph.edges = std::move(now.edges);
            side = std::async(std::launch::async,
                              [&while_meshing, &final_graph] { while_meshing(final_graph); });
        }
        if (progress && total > 0 && !side.valid()) {
            progress(now.solved < total ? "actor graph: keyframes in" : "actor graph: certifying",
                     0.9 * static_cast<double>(now.solved) / static_cast<double>(total));
        }
    }
    result.seconds = std::chrono::duration<double>(Clock::now() - start).count();
    Collect(nodes, &result);
    actors::MapperActor* mapper = nodes.front()->Mapper();
    if (mapper && progress && !side.valid()) {
        progress("actor graph: fusing the mappers' submaps", 0.95);
    }
    if (while_meshing && (!side.valid() || !SameEdges(final_graph.edges, result.edges))) {
        // Never final (a timeout) or not final after all: the side work on the end's edges.
        if (side.valid()) side.get();
        final_graph.edges = result.edges;
        side = std::async(std::launch::async,
                          [&while_meshing, &final_graph] { while_meshing(final_graph); });
    }
    if (mapper) {
        // Two publish periods: the last re-anchorings reach robot 0's mapper.
        std::this_thread::sleep_for(2 * config.mapper.publish_period);
        const auto mesh_start = Clock::now();
        result.mesh = mapper->FusedMesh(voxel_m);
        result.mesh_seconds = std::chrono::duration<double>(Clock::now() - mesh_start).count();
        result.submaps = mapper->Stats().own_submaps + mapper->Stats().peer_submaps;
        for (auto& node : nodes) {
            if (node->Mapper()) result.map_bytes_sent += node->Mapper()->Stats().submap_bytes_sent;
        }
    }
    if (side.valid()) side.get();
    const auto stop_start = Clock::now();
    for (auto& node : nodes) node->Stop();
    result.stop_seconds = std::chrono::duration<double>(Clock::now() - stop_start).count();
    return result;
}

}  // namespace certislam::bin
