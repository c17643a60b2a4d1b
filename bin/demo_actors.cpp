// One RobotNode per robot, inproc wiring, keyframes served from memory, poll until done.
#include "bin/demo_actors.h"

#include <chrono>
#include <memory>
#include <thread>
#include <zmq.hpp>

#include "actors/robot_node.h"
#include "actors/wiring.h"

namespace certislam::bin {

ActorMissionResult RunThroughActors(const std::vector<std::vector<slam::Keyframe>>& robots,
                                    double timeout_s) {
    using Clock = std::chrono::steady_clock;
    const auto start = Clock::now();
    std::vector<int> ids;
    for (size_t r = 0; r < robots.size(); ++r) ids.push_back(static_cast<int>(r));
    actors::RobotNodeConfig config;  // deploy/configs/sim2.json's, but every keyframe queries
    config.solver.solver.rank = 5;   // like the direct pipeline (query_stride 1)
    config.solver.solver.rbcd.rel_grad_tol = 1e-9;
    config.matcher.query_stride = 1;
    config.matcher.max_sc_distance = 0.2;
    zmq::context_t context;
    std::vector<std::unique_ptr<actors::RobotNode>> nodes;
    for (int r : ids) {
        auto next = std::make_shared<size_t>(0);
        const auto* keyframes = &robots[static_cast<size_t>(r)];
        actors::KeyframeSource source = [keyframes, next]() -> std::optional<slam::Keyframe> {
            if (*next >= keyframes->size()) return std::nullopt;
            return (*keyframes)[(*next)++];
        };
        nodes.push_back(std::make_unique<actors::RobotNode>(context, actors::InprocWiring(r, ids),
                                                            std::move(source), config));
    }
    for (auto& node : nodes) node->Start();
    ActorMissionResult result;
    const auto deadline = start + std::chrono::duration<double>(timeout_s);
    while (!result.done && Clock::now() < deadline) {
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
        result.done = true;
        for (auto& node : nodes) result.done = result.done && node->Done();
    }
    result.seconds = std::chrono::duration<double>(Clock::now() - start).count();
    for (auto& node : nodes) {
        const actors::SolverSnapshot snapshot = node->Snapshot();
        result.trajectory.push_back(snapshot.trajectory);
        result.inter_robot_loops.push_back(snapshot.inter_robot_loops);
        const bool certified =
            snapshot.report && snapshot.report->verdict() == v1::CERTIFICATE_VERDICT_CERTIFIED;
        result.certified = (result.trajectory.size() == 1 || result.certified) && certified;
        result.bytes_sent += node->BytesSentToPeers();
    }
    for (auto& node : nodes) node->Stop();
    return result;
}

}  // namespace certislam::bin
