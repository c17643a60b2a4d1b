// A whole team of pose-graph robots in one process over inproc: each robot its own source,
// solver and certifier actors on real sockets; runs until every robot is done (certified and
// quiet) or a timeout, and says what it cost (team rounds, bytes between robots, certificate).
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "actors/pose_graph_node.h"
#include "certislam/v1/certificate.pb.h"
#include "slam/core/graph_split.h"

namespace certislam::actors {

/// What a pose-graph team run gave.
struct PoseGraphTeamResult {
    bool done = false;  ///< every robot certified and quiet before the timeout
    std::optional<v1::CertificateReport> report;  ///< last certificate robot 0's solver heard
    std::uint64_t iterations = 0;  ///< team rounds: the most block updates of any robot
    std::map<int, std::uint64_t> iterations_by_robot;     ///< block updates per robot
    std::uint64_t bytes_between_robots = 0;               ///< every actor's bytes to peers
    std::map<std::string, std::uint64_t> bytes_by_actor;  ///< summed over robots
    std::map<int, std::uint64_t> bytes_by_robot;          ///< summed over actors
    double seconds = 0.0;                                 ///< wall time, start to done
    /// Wall time from the start until every robot's rounds had converged (or -1: never), and
    /// until robot 0's solver first heard a certified report (or -1)
    double seconds_to_converged = -1.0;
    double seconds_to_certified = -1.0;
    int certificate_rounds = 0;        ///< distributed rounds robot 0's certifier finished
    std::uint64_t lanczos_steps = 0;   ///< S v products of those rounds (robot 0's count)
    double certificate_seconds = 0.0;  ///< wall seconds of those rounds (robot 0's share)
    int escapes = 0;                   ///< saddle escapes sent (anchor)
    int rank = 0;                      ///< robot 0's relaxation rank at the end
    /// "synchronous": every robot's RBCD++ rounds (or their finish) reached the tolerance;
    /// "asynchronous": some robot gave up its rounds (or never ran them) and went on with
    /// asynchronous updates; "rounds running": none did, but some robot's rounds or finish had
    /// not converged yet (a timeout in the rounds).
    std::string solver_mode = "asynchronous";
    int restarts = 0;  ///< adaptive restarts of the rounds (robot 0's count)
    /// Overlapping sweeps' proposals the robots dropped (summed; SolverSnapshot)
    std::uint64_t rejected_proposals = 0;
    /// Round messages re-sent because a stalled robot asked for them (summed; SolverSnapshot)
    std::uint64_t round_resends = 0;
    int overlap_ends = 0;  ///< runs of the rounds whose overlap a rise of f ended (robot 0's count)
    int fallbacks = 0;     ///< certificate rounds the anchor checked centrally instead
    /// How far the poses leave the plane z = 0 (a planar graph's lift, slam::LiftPlanar): the
    /// largest |z| and the largest tilt of a pose's z axis
    double out_of_plane_m = 0.0;
    double out_of_plane_rad = 0.0;
    /// The file's cost minus the team's for every X (merged parallel edges, slam::CostOffset):
    /// the report's objective and lower bound plus this are the file's.
    double cost_offset = 0.0;
    /// The team's second-order finish after rounds that did not converge (SolverSnapshot::finish;
    /// robot 0's counters, which every robot shares but its bytes): trust-region steps, CG
    /// iterations, neighbour exchanges, sums, and how the last one ended ("" when none ran)
    int finish_steps = 0;
    int finish_cg_iterations = 0;
    std::uint64_t finish_exchanges = 0;
    std::uint64_t finish_reductions = 0;
    std::string finish_status;
    std::uint64_t finish_dropped = 0;  ///< finish messages the robots dropped (summed)
    double finish_seconds = 0.0;       ///< robot 0's wall time in the finish
};

/// solver_mode's value while the rounds run (PoseGraphTeamResult::solver_mode).
inline constexpr const char* kRoundsRunning = "rounds running";

/// solver_mode from every robot's rounds converged (`sync`), and every robot's converged or
/// still running (`in_rounds`: none went asynchronous).
inline std::string SolverMode(bool sync, bool in_rounds) {
    if (sync) return "synchronous";
    return in_rounds ? kRoundsRunning : "asynchronous";
}

/// What `nodes` (the anchor first; PoseGraphNode or RobotNode) have done so far: counters summed
/// or maxed over them, the anchor's report and certificate counters; `done` and `seconds` are
/// left to the caller.
template <typename Node>
PoseGraphTeamResult SummariseNodes(const std::vector<const Node*>& nodes) {
    PoseGraphTeamResult out;
    bool sync = true, in_rounds = true;
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
        out.round_resends += s.round_resends;
        out.finish_dropped += s.finish_dropped + s.finish.dropped;
        for (const auto& pose : s.trajectory) {
            const Eigen::Isometry3d& T = pose.T_world_body;
            out.out_of_plane_m = std::max(out.out_of_plane_m, std::abs(T.translation().z()));
            const double cos_tilt = std::clamp(T.linear()(2, 2), -1.0, 1.0);
            out.out_of_plane_rad = std::max(out.out_of_plane_rad, std::acos(cos_tilt));
        }
        const bool converged = s.rounds_converged && !s.rounds_gave_up;
        sync = sync && converged;
        in_rounds = in_rounds && (converged || s.rounds_running);
    }
    out.solver_mode = SolverMode(sync, in_rounds);
    if (nodes.empty()) return out;
    const Node& anchor = *nodes.front();
    const SolverSnapshot s = anchor.Snapshot();
    out.report = s.report;
    out.rank = s.rank;
    out.restarts = s.restarts;
    out.overlap_ends = s.overlap_ends;
    out.finish_steps = s.finish.iterations;
    out.finish_cg_iterations = s.finish.tcg_iterations;
    out.finish_exchanges = s.finish.exchanges;
    out.finish_reductions = s.finish.reductions;
    out.finish_status = s.finish_status;
    out.finish_seconds = s.finish_seconds;
    out.fallbacks = anchor.Certifier().Fallbacks();
    out.certificate_rounds = anchor.Certifier().Rounds();
    out.lanczos_steps = anchor.Certifier().LanczosSteps();
    out.certificate_seconds = anchor.Certifier().RoundSeconds();
    return out;
}

/// Runs `graphs` (robot k = graphs[k].robot, ascending from 0) in one process over inproc until
/// all are done or `timeout` passes.
PoseGraphTeamResult RunPoseGraphTeam(const std::vector<slam::RobotGraph>& graphs,
                                     const PoseGraphNodeConfig& config,
                                     std::chrono::duration<double> timeout);

}  // namespace certislam::actors
