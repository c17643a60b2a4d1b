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

RelativePoseMeasurement Edge(int i, int j, const Eigen::Isometry3d& T_i_j, double sigma_t,
                             double sigma_r) {
    RelativePoseMeasurement m;
    m.i = i;
    m.j = j;
    m.R = T_i_j.linear();
    m.t = T_i_j.translation();
    m.tau = 1.0 / (sigma_t * sigma_t);
    m.kappa = 1.0 / (2.0 * sigma_r * sigma_r);
    return m;
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

/// One Riemannian staircase step (MATH.md, "Saddle escape"): lift X to rank r+1 and move along
/// e_{r+1} v^T, halving the step until the cost decreases.
Eigen::MatrixXd EscapeSaddle(const Eigen::SparseMatrix<double>& Q, const Eigen::MatrixXd& X,
                             const Eigen::VectorXd& v) {
    const int r = static_cast<int>(X.rows());
    Eigen::MatrixXd X_plus = Eigen::MatrixXd::Zero(r + 1, X.cols());
    X_plus.topRows(r) = X;
    const double f0 = LiftedCost(Q, X_plus);
    Eigen::MatrixXd direction = Eigen::MatrixXd::Zero(r + 1, X.cols());
    direction.row(r) = v.transpose();
    for (double alpha = 1e2 * std::max(1.0, X.norm()); alpha > 1e-10; alpha *= 0.5) {
        Eigen::MatrixXd candidate = Retract(X_plus, alpha * direction, 3);
        if (LiftedCost(Q, candidate) < f0) return candidate;
    }
    return X_plus;
}

}  // namespace

void EdgeNoiseConfig::Validate() const {
    Require(odometry_sigma_t_m > 0, "EdgeNoiseConfig.odometry_sigma_t_m", odometry_sigma_t_m,
            "must be > 0");
    Require(odometry_sigma_r_rad > 0, "EdgeNoiseConfig.odometry_sigma_r_rad", odometry_sigma_r_rad,
            "must be > 0");
    Require(loop_sigma_t_m > 0, "EdgeNoiseConfig.loop_sigma_t_m", loop_sigma_t_m, "must be > 0");
    Require(loop_sigma_r_rad > 0, "EdgeNoiseConfig.loop_sigma_r_rad", loop_sigma_r_rad,
            "must be > 0");
}

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
                auto edge =
                    Edge(graph.n - 1, graph.n, odometry[r][i - 1].inverse() * odometry[r][i],
                         noise.odometry_sigma_t_m, noise.odometry_sigma_r_rad);
                edge.is_known_inlier = true;
                graph.edges.push_back(edge);
            }
            ++graph.n;
        }
    }
    for (const auto& loop : loops) {
        CERTISLAM_CHECK(loop.a.robot >= 0 && loop.a.robot < static_cast<int>(odometry.size()));
        CERTISLAM_CHECK(loop.b.robot >= 0 && loop.b.robot < static_cast<int>(odometry.size()));
        graph.edges.push_back(Edge(offset[loop.a.robot] + loop.a.index,
                                   offset[loop.b.robot] + loop.b.index, loop.T_a_b,
                                   noise.loop_sigma_t_m, noise.loop_sigma_r_rad));
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
    JointSolution solution;
    const Partition partition = PartitionFromIds(graph);
    const Eigen::SparseMatrix<double> Q = ConnectionLaplacian(graph);
    Eigen::MatrixXd X = LiftToRank(ChordalInitialization(graph), config.rank);
    for (int step = 0;; ++step) {
        const RbcdResult rbcd = SolveRbcd(graph, partition, X, config.rbcd);
        solution.rbcd_status = rbcd.status;
        solution.iterations += rbcd.iterations;
        solution.rank = static_cast<int>(rbcd.X.rows());
        solution.certificate = certify::Certify(Q, rbcd.X, 3, config.certificate);
        X = rbcd.X;
        const bool saddle =
            solution.certificate.status == certify::CertificateResult::Status::kNotCertified;
        if (!saddle || step >= config.max_staircase_steps) break;
        X = EscapeSaddle(Q, X, solution.certificate.eigenvector);
        ++solution.staircase_steps;
    }
    solution.poses = Anchor(RoundSolution(graph, X));
    solution.cost = Objective(graph, solution.poses);
    solution.seconds = Seconds(start);
    return solution;
}

LocalSearchRun LocalSearchJoint(const PoseGraph& graph, const PoseMatrix& initial,
                                const MissionSolverConfig& config) {
    const auto start = std::chrono::steady_clock::now();
    const LmResult lm = SolveLm(graph, initial, config.local_search);
    LocalSearchRun run;
    run.poses = Anchor(lm.poses);
    run.status = lm.status;
    run.initial_cost = lm.initial_cost;
    run.cost = Objective(graph, run.poses);
    run.iterations = lm.iterations;
    run.certificate =
        certify::Certify(ConnectionLaplacian(graph), run.poses, 3, config.certificate);
    run.seconds = Seconds(start);
    return run;
}

MissionResult RunMission(const std::vector<std::vector<Keyframe>>& robots,
                         const std::vector<std::vector<Eigen::Isometry3d>>& truth,
                         const MissionConfig& config, const MissionProgress& progress) {
    config.Validate();
    if (robots.empty() || robots[0].empty()) {
        throw std::invalid_argument("robots: robot 0 has no keyframes (it anchors the team frame)");
    }
    const auto report = [&](const std::string& stage, double f) {
        if (progress) progress(stage, f);
    };
    MissionResult result;
    auto start = std::chrono::steady_clock::now();
    report("loop closures", 0.0);
    auto loops = DetectLoops(robots, truth, config.loops);
    result.loops = std::move(loops.loops);
    result.loop_stats = loops.stats;
    result.warnings = std::move(loops.warnings);
    result.front_end_seconds = Seconds(start);

    start = std::chrono::steady_clock::now();
    report("baselines", 0.5);
    std::vector<std::vector<Eigen::Isometry3d>> odometry(robots.size());
    for (size_t r = 0; r < robots.size(); ++r) {
        for (const auto& kf : robots[r]) odometry[r].push_back(kf.T_odom_sensor);
    }
    result.graph = BuildJointGraph(odometry, result.loops, config.noise);
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
    report("certified RBCD", 0.75);
    result.solution = SolveCertifiedJoint(result.graph, config.solver);
    result.solution.poses = InTeamFrame(T_team_first, result.solution.poses);
    result.certified = SplitTrajectories(result.graph, result.solution.poses, robots);
    if (result.status == MissionResult::Status::kOk &&
        result.solution.certificate.status != certify::CertificateResult::Status::kCertified) {
        result.status = MissionResult::Status::kNotCertified;
    }
    result.back_end_seconds = Seconds(start);
    report("done", 1.0);
    return result;
}

}  // namespace certislam::certify
