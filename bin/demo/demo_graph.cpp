// The demo's one front end: baselines on the actors' team graph, certified row from the actors.
#include "bin/demo/demo_graph.h"

#include <algorithm>
#include <cstdio>

#include "slam/backend/connection_laplacian.h"

namespace certislam::bin {
namespace {

bool IsOdometry(const slam::LoopClosure& e) {
    return e.a.robot == e.b.robot && e.b.index == e.a.index + 1;
}

std::vector<int> PosesPerRobot(const std::vector<std::vector<slam::Keyframe>>& robots) {
    std::vector<int> poses;
    poses.reserve(robots.size());
    for (const auto& r : robots) poses.push_back(static_cast<int>(r.size()));
    return poses;
}

/// Poses (3 x 4n, robots contiguous as in `graph`) of per-robot trajectories.
slam::PoseMatrix Stack(const slam::PoseGraph& graph, const std::vector<slam::Trajectory>& traj) {
    slam::PoseMatrix poses(3, 4 * graph.n);
    for (int g = 0; g < graph.n; ++g) {
        const slam::PoseId id = graph.ids[g];
        poses.block<3, 4>(0, 4 * g) = traj[id.robot][id.index].T_world_body.matrix().topRows<3>();
    }
    return poses;
}

void ActorGraphJson(const ActorMissionResult& run, double objective, DemoReport* report) {
    report->actor_graph = {{"done", run.done},
                           {"certified", run.certified},
                           {"verdict", run.verdict},
                           {"certificate_path", run.certificate_path},
                           {"seconds", run.seconds},
                           {"bytes_sent_measured", run.bytes_sent},
                           {"inter_robot_loops_per_robot", run.inter_robot_loops},
                           {"loops_accepted_per_matcher", run.loops_found},
                           {"registrations_per_matcher", run.registrations},
                           {"loops_verified_per_matcher", run.loops_verified},
                           {"solver_steps", run.solver_steps},
                           {"map_submaps", run.submaps},
                           {"map_bytes_sent", run.map_bytes_sent},
                           {"certificate_rounds", run.certificate_rounds},
                           {"saddle_escapes", run.saddle_escapes},
                           {"lanczos_steps", run.lanczos_steps},
                           {"settled_skips", run.settled_skips},
                           {"bytes_by_actor", run.bytes_by_actor},
                           {"mesh_triangles", run.mesh.triangles.size()},
                           {"anchor", run.anchor},
                           {"team_graph_edges", run.edges.size()},
                           {"objective_of_trajectory_on_team_graph", objective}};
}

}  // namespace

std::vector<slam::LoopClosure> LoopsInDiscoveryOrder(
    const std::vector<std::vector<slam::Keyframe>>& robots,
    const std::vector<slam::LoopClosure>& edges) {
    std::vector<slam::LoopClosure> loops;
    for (const auto& e : edges) {
        if (!IsOdometry(e)) loops.push_back(e);
    }
    const auto stamps = [&](const slam::LoopClosure& l) {
        const auto a = robots[l.a.robot][l.a.index].stamp_ns;
        const auto b = robots[l.b.robot][l.b.index].stamp_ns;
        return std::pair{std::max(a, b), std::min(a, b)};
    };
    std::stable_sort(loops.begin(), loops.end(),
                     [&](const auto& x, const auto& y) { return stamps(x) < stamps(y); });
    return loops;
}

certify::MissionResult BaselinesOnActorGraph(const std::vector<std::vector<slam::Keyframe>>& robots,
                                             const ActorMissionResult& run,
                                             const certify::MissionConfig& config,
                                             const certify::MissionProgress& progress) {
    const std::vector<int> poses = PosesPerRobot(robots);
    std::vector<slam::LoopClosure> known;  // edges whose ends the keyframes have
    for (const auto& e : run.edges) {
        const auto ok = [&](const slam::PoseId& id) {
            return id.robot >= 0 && id.robot < static_cast<int>(robots.size()) && id.index >= 0 &&
                   id.index < poses[id.robot];
        };
        if (ok(e.a) && ok(e.b)) known.push_back(e);
    }
    return certify::SolveMissionGraph(robots, LoopsInDiscoveryOrder(robots, known),
                                      certify::GraphFromEdges(poses, known), config, false,
                                      progress);
}

void FillFromActors(const ActorMissionResult& run, certify::MissionResult* mission,
                    DemoReport* report) {
    mission->certified = run.trajectory;
    double objective = -1.0;
    bool complete = run.trajectory.size() == static_cast<size_t>(mission->odometry.size());
    for (size_t r = 0; complete && r < run.trajectory.size(); ++r) {
        complete = run.trajectory[r].size() == mission->odometry[r].size();
    }
    if (complete) {
        mission->solution.poses = Stack(mission->graph, run.trajectory);
        objective = slam::Objective(mission->graph, mission->solution.poses);
    } else {
        mission->certified = mission->odometry;  // keeps the table whole; said loudly below
        mission->solution.poses = Stack(mission->graph, mission->odometry);
        report->warnings.push_back(
            "actor graph: some robot's solver does not hold all its "
            "keyframes; its certified row shows odometry");
    }
    mission->solution.cost = run.cost;
    report->certified = run.done && run.certified;
    report->lambda_min = run.lambda_min;
    report->verdict = run.verdict;
    report->has_bound = run.has_bound;
    report->suboptimality_bound = run.suboptimality_bound;
    report->lower_bound = run.lower_bound;  // as the certificate proved them (0 unless has_bound)
    report->relative_suboptimality_bound = run.relative_suboptimality_bound;
    report->cost = run.cost;
    report->rank = run.rank;
    report->rbcd_iterations = 0;
    for (const auto steps : run.solver_steps) report->rbcd_iterations += static_cast<int>(steps);
    report->bytes_sent = static_cast<std::int64_t>(run.bytes_sent);
    report->bytes_note =
        "measured on the actor graph's sockets: every message sent on an edge that reaches "
        "another robot (descriptors, cloud requests and replies, loop closures, public poses, "
        "certificate traffic), envelope and frames";
    ActorGraphJson(run, objective, report);
    if (!run.done) {
        char buf[160];
        std::snprintf(buf, sizeof(buf),
                      "actor graph: not every robot was certified and quiet within %.1f s",
                      run.seconds);
        report->warnings.push_back(buf);
    }
}

}  // namespace certislam::bin
