// The multi-robot pipeline: loops, joint graph, baselines, certified RBCD (paper Sec. II).
#include "certify/pipeline/mission.h"

#include <chrono>
#include <stdexcept>

#include "slam/backend/chordal.h"
#include "slam/backend/connection_laplacian.h"
#include "slam/backend/lm_baseline.h"
#include "slam/backend/one_time_alignment.h"
#include "slam/backend/rounding.h"
#include "slam/backend/stiefel.h"
#include "slam/core/check.h"
#include "slam/core/partition.h"

namespace certislam::certify {
using namespace slam;  // NOLINT(google-build-using-namespace): the pipeline is all slam types
namespace {

void Require(bool ok, const std::string& what, double value, const std::string& rule) {
    if (!ok) throw std::invalid_argument(what + " = " + std::to_string(value) + ": " + rule);
}

double Seconds(std::chrono::steady_clock::time_point since) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

/// Poses (3 x 4n) moved so pose 0 is the identity: the team frame is robot 0's odometry frame.
PoseMatrix Anchor(const PoseMatrix& poses) {
    const int n = static_cast<int>(poses.cols() / 4);
    const Eigen::Matrix3d R0 = poses.block<3, 3>(0, 0);
    const Eigen::Vector3d t0 = poses.col(3);
    PoseMatrix out(3, 4 * n);
    for (int g = 0; g < n; ++g) {
        out.block<3, 3>(0, 4 * g) = R0.transpose() * poses.block<3, 3>(0, 4 * g);
        out.col(4 * g + 3) = R0.transpose() * (poses.col(4 * g + 3) - t0);
    }
    return out;
}

// Poses anchored at pose 0 = identity, re-expressed in the frame where pose 0 is T_team_first
// (the team frame is robot 0's odometry frame, so pose 0 is robot 0's first odometry pose).
PoseMatrix InTeamFrame(const Eigen::Isometry3d& T_team_first, const PoseMatrix& anchored) {
    const int n = static_cast<int>(anchored.cols() / 4);
    PoseMatrix out(3, 4 * n);
    const Eigen::Matrix3d R = T_team_first.linear();
    for (int g = 0; g < n; ++g) {
        out.block<3, 3>(0, 4 * g) = R * anchored.block<3, 3>(0, 4 * g);
        out.col(4 * g + 3) = R * anchored.col(4 * g + 3) + T_team_first.translation();
    }
    return out;
}

PoseMatrix FromIsometries(const std::vector<std::vector<Eigen::Isometry3d>>& poses) {
    int n = 0;
    for (const auto& robot : poses) n += static_cast<int>(robot.size());
    PoseMatrix out(3, 4 * n);
    int g = 0;
    for (const auto& robot : poses) {
        for (const auto& T : robot) out.block<3, 4>(0, 4 * g++) = T.matrix().topRows<3>();
    }
    return out;
}

}  // namespace

void MissionSolverConfig::Validate() const {
    Require(rank >= 3, "MissionSolverConfig.rank", rank, "must be >= 3");
    Require(max_staircase_steps >= 0, "MissionSolverConfig.max_staircase_steps",
            max_staircase_steps, "must be >= 0");
    rbcd.Validate();
    certificate.Validate();
    local_search.Validate();
}

void MissionConfig::Validate() const {
    noise.Validate();
    loops.Validate();
    solver.Validate();
}

PoseGraph BuildJointGraph(const std::vector<std::vector<Eigen::Isometry3d>>& odometry,
                          const std::vector<LoopClosure>& loops, const EdgeNoiseConfig& noise) {
    PoseGraph graph;
    graph.d = 3;
    std::vector<int> offset;
    for (size_t r = 0; r < odometry.size(); ++r) {
        offset.push_back(graph.n);
        for (size_t i = 0; i < odometry[r].size(); ++i) {
            graph.ids.push_back({static_cast<int>(r), static_cast<int>(i)});
            if (i > 0) {
                auto edge = MeasurementOf(graph.n - 1, graph.n,
                                          odometry[r][i - 1].inverse() * odometry[r][i],
                                          RotationWeight(noise.odometry_sigma_r_rad),
                                          TranslationWeight(noise.odometry_sigma_t_m));
                edge.is_known_inlier = true;
                graph.edges.push_back(edge);
            }
            ++graph.n;
        }
    }
    for (const auto& loop : loops) {
        CERTISLAM_CHECK(loop.a.robot >= 0 && loop.a.robot < static_cast<int>(odometry.size()));
        CERTISLAM_CHECK(loop.b.robot >= 0 && loop.b.robot < static_cast<int>(odometry.size()));
        graph.edges.push_back(MeasurementOf(
            offset[loop.a.robot] + loop.a.index, offset[loop.b.robot] + loop.b.index, loop.T_a_b,
            RotationWeight(noise.loop_sigma_r_rad), TranslationWeight(noise.loop_sigma_t_m)));
    }
    return graph;
}

std::vector<Trajectory> SplitTrajectories(const PoseGraph& graph, const PoseMatrix& poses,
                                          const std::vector<std::vector<Keyframe>>& robots) {
    std::vector<Trajectory> out(robots.size());
    for (int g = 0; g < graph.n; ++g) {
        const PoseId id = graph.ids[g];
        StampedPose p;
        p.stamp_s = static_cast<double>(robots[id.robot][id.index].stamp_ns) * 1e-9;
        p.T_world_body.matrix().topRows<3>() = poses.block<3, 4>(0, 4 * g);
        out[id.robot].push_back(p);
    }
    return out;
}

JointSolution SolveCertifiedJoint(const PoseGraph& graph, const MissionSolverConfig& config) {
    config.Validate();
    const auto start = std::chrono::steady_clock::now();
    StaircaseConfig stairs;
    stairs.rbcd = config.rbcd;
    stairs.certificate = config.certificate;
    stairs.max_rank = config.rank + config.max_staircase_steps;
    const StaircaseResult solved =
        SolveCertified(graph, PartitionFromIds(graph),
                       LiftToRank(ChordalInitialization(graph), config.rank), stairs);
    JointSolution solution;
    solution.status = solved.status;
    solution.rank = solved.rank;
    solution.iterations = solved.iterations;
    solution.staircase_steps = solved.escapes;
    solution.certificate = solved.certificate;
    solution.poses = Anchor(RoundSolution(graph, solved.X));
    solution.cost = Objective(graph, solution.poses);
    solution.seconds = Seconds(start);
    return solution;
}

LocalSearchRun LocalSearchJoint(const PoseGraph& graph, const PoseMatrix& initial,
                                const MissionSolverConfig& config) {
    const auto start = std::chrono::steady_clock::now();
    const LmResult lm = SolveLm(graph, initial, config.local_search);
    LocalSearchPolishConfig polish;
    polish.certificate = config.certificate;
    const LocalSearchCertificate judged = CertifyLocalSearch(graph, lm.poses, polish);
    LocalSearchRun run;
    run.poses = Anchor(judged.poses);
    run.status = lm.status;
    run.initial_cost = lm.initial_cost;
    run.lm_cost = lm.cost;
    run.cost = Objective(graph, run.poses);
    run.iterations = lm.iterations;
    run.certificate = judged.certificate;
    run.seconds = Seconds(start);
    return run;
}

PoseGraph GraphFromEdges(const std::vector<int>& poses, const std::vector<LoopClosure>& edges) {
    PoseGraph graph;
    graph.d = 3;
    std::vector<int> offset;
    for (size_t r = 0; r < poses.size(); ++r) {
        offset.push_back(graph.n);
        for (int i = 0; i < poses[r]; ++i) graph.ids.push_back({static_cast<int>(r), i});
        graph.n += poses[r];
    }
    const auto valid = [&](const PoseId& id) {
        return id.robot >= 0 && id.robot < static_cast<int>(poses.size()) && id.index >= 0 &&
               id.index < poses[id.robot];
    };
    for (const auto& e : edges) {
        if (!valid(e.a) || !valid(e.b)) continue;
        auto m = MeasurementOf(offset[e.a.robot] + e.a.index, offset[e.b.robot] + e.b.index,
                               e.T_a_b, e.kappa, e.tau);
        m.is_known_inlier = e.a.robot == e.b.robot && e.b.index == e.a.index + 1;
        graph.edges.push_back(m);
    }
    return graph;
}

MissionResult SolveMissionGraph(const std::vector<std::vector<Keyframe>>& robots,
                                std::vector<LoopClosure> loops, PoseGraph graph,
                                const MissionConfig& config, bool certified_rbcd,
                                const MissionProgress& progress) {
    config.Validate();
    const auto report = [&](const std::string& stage, double f) {
        if (progress) progress(stage, f);
    };
    const auto start = std::chrono::steady_clock::now();
    MissionResult result;
    result.loops = std::move(loops);
    result.graph = std::move(graph);
    report("baselines", 0.5);
    std::vector<std::vector<Eigen::Isometry3d>> odometry(robots.size());
    for (size_t r = 0; r < robots.size(); ++r) {
        for (const auto& kf : robots[r]) odometry[r].push_back(kf.T_odom_sensor);
    }
    result.odometry = SplitTrajectories(result.graph, FromIsometries(odometry), robots);
    const auto one_time = OneTimeAlignment(odometry, result.loops);
    const PoseMatrix one_time_poses = FromIsometries(one_time.poses);
    result.one_time_alignment = SplitTrajectories(result.graph, one_time_poses, robots);
    for (size_t r = 1; r < robots.size(); ++r) {
        if (!one_time.T_team_odom[r]) {
            // The joint graph is disconnected: no joint solution (chordal init is singular).
            throw std::runtime_error("robot " + std::to_string(r) +
                                     " met no robot of the team (no inter-robot loop closure "
                                     "joins it): the joint pose graph is disconnected");
        }
    }
    report("local search (LM)", 0.6);
    result.local_search_from_odometry =
        LocalSearchJoint(result.graph, FromIsometries(odometry), config.solver);
    result.local_search_from_alignment =
        LocalSearchJoint(result.graph, one_time_poses, config.solver);
    const Eigen::Isometry3d& T_team_first = odometry[0][0];
    for (auto* run : {&result.local_search_from_odometry, &result.local_search_from_alignment}) {
        run->poses = InTeamFrame(T_team_first, run->poses);
    }
    result.local_search =
        SplitTrajectories(result.graph, result.local_search_from_odometry.poses, robots);
    if (certified_rbcd) {
        report("certified RBCD", 0.75);
        result.solution = SolveCertifiedJoint(result.graph, config.solver);
        result.solution.poses = InTeamFrame(T_team_first, result.solution.poses);
        result.certified = SplitTrajectories(result.graph, result.solution.poses, robots);
        if (result.solution.certificate.status != certify::CertificateResult::Status::kCertified) {
            result.status = MissionResult::Status::kNotCertified;
        }
    }
    result.back_end_seconds = Seconds(start);
    report("done", 1.0);
    return result;
}

MissionResult RunMission(const std::vector<std::vector<Keyframe>>& robots,
                         const std::vector<std::vector<Eigen::Isometry3d>>& truth,
                         const MissionConfig& config, const MissionProgress& progress) {
    config.Validate();
    if (robots.empty() || robots[0].empty()) {
        throw std::invalid_argument("robots: robot 0 has no keyframes (it anchors the team frame)");
    }
    if (progress) progress("loop closures", 0.0);
    const auto start = std::chrono::steady_clock::now();
    auto loops = DetectLoops(robots, truth, config.loops);
    const double front_end_seconds = Seconds(start);
    std::vector<std::vector<Eigen::Isometry3d>> odometry(robots.size());
    for (size_t r = 0; r < robots.size(); ++r) {
        for (const auto& kf : robots[r]) odometry[r].push_back(kf.T_odom_sensor);
    }
    PoseGraph graph = BuildJointGraph(odometry, loops.loops, config.noise);
    MissionResult result =
        SolveMissionGraph(robots, std::move(loops.loops), std::move(graph), config, true, progress);
    result.loop_stats = loops.stats;
    result.warnings = std::move(loops.warnings);
    result.front_end_seconds = front_end_seconds;
    return result;
}

}  // namespace certislam::certify
