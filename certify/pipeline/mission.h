// The multi-robot pipeline as one pure function: keyframes of N robots in; loop closures,
// the joint pose graph, the four methods' trajectories (odometry, one-time alignment, local
// search, certified RBCD) and the certificate out. Actors run the same pieces one by one.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "certify/certificate.h"
#include "certify/local_search.h"
#include "certify/pipeline/edge_noise.h"
#include "certify/staircase.h"
#include "slam/backend/lm_baseline.h"
#include "slam/backend/rbcd.h"
#include "slam/core/keyframe.h"
#include "slam/core/loop_closure.h"
#include "slam/core/pose_graph.h"
#include "slam/core/trajectory.h"
#include "slam/frontend/loop_detection.h"

namespace certislam::certify {

/// The back end's settings.
struct MissionSolverConfig {
    int rank = 5;                   ///< relaxation rank r >= 3 of certified RBCD
    slam::RbcdConfig rbcd;          ///< RBCD (one block per robot)
    CertificateConfig certificate;  ///< the certifier
    int max_staircase_steps = 3;    ///< saddle escapes (rank r -> r+1) at most, >= 0
    slam::LmConfig local_search;    ///< the local-search baseline (Levenberg-Marquardt, Ceres)

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// Everything the pipeline depends on.
struct MissionConfig {
    EdgeNoiseConfig noise;            ///< edge weights
    slam::LoopDetectionConfig loops;  ///< Scan Context, verification, outlier rejection
    MissionSolverConfig solver;       ///< RBCD + certificate

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// The solution of the joint graph by certified RBCD.
struct JointSolution {
    /// 3 x 4n: pose 0 = identity from SolveCertifiedJoint, the team frame from RunMission.
    slam::PoseMatrix poses;
    StaircaseResult::Status status = StaircaseResult::Status::kNotCritical;  ///< the staircase's
    int rank = 0;                   ///< rank of the final (certified) run
    int iterations = 0;             ///< RBCD iterations over all staircase steps
    int staircase_steps = 0;        ///< saddle escapes taken
    double cost = 0.0;              ///< f of the rounded poses (SE-Sync objective)
    double seconds = 0.0;           ///< solve + certify
    CertificateResult certificate;  ///< of the final lifted point
};

/// One run of the local-search baseline (LM) from one initial guess, and its certificate.
struct LocalSearchRun {
    /// 3 x 4n: pose 0 = identity from LocalSearchJoint, the team frame from RunMission.
    slam::PoseMatrix poses;
    slam::LmResult::Status status = slam::LmResult::Status::kFailed;  ///< LM's outcome
    double initial_cost = 0.0;                                        ///< f at the guess
    double lm_cost = 0.0;                                             ///< f where LM stopped
    double cost = 0.0;              ///< f at the LM solution polished on f (CertifyLocalSearch)
    int iterations = 0;             ///< LM iterations
    double seconds = 0.0;           ///< LM + certificate
    CertificateResult certificate;  ///< what the certificate says of the polished LM solution
};

/// What the pipeline gives: per-robot trajectories of the four methods, all but odometry in the
/// team frame (robot 0's odometry frame); odometry in each robot's own frame.
struct MissionResult {
    enum class Status { kOk, kNoInterRobotLoops, kNotCertified };
    Status status = Status::kOk;
    std::vector<slam::Trajectory> odometry;            ///< [robot], own odometry frames
    std::vector<slam::Trajectory> one_time_alignment;  ///< [robot], DiSCo-style first encounter
    std::vector<slam::Trajectory> local_search;        ///< [robot], LM from odometry
    std::vector<slam::Trajectory> certified;           ///< [robot], certified RBCD
    std::vector<slam::LoopClosure> loops;              ///< accepted loop closures, discovery order
    slam::LoopDetectionStats loop_stats;               ///< candidates, verified, rejected, ...
    slam::PoseGraph graph;                             ///< the joint graph, robots contiguous
    JointSolution solution;  ///< certified RBCD's solution and certificate
    /// Local search as the issue defines it: LM from odometry, every robot's odometry frame
    /// taken as the team frame (what a robot knows before any alignment).
    LocalSearchRun local_search_from_odometry;
    /// LM from the one-time alignment (the DiSCo-style guess): the stronger local baseline.
    LocalSearchRun local_search_from_alignment;
    std::vector<std::string> warnings;  ///< fallbacks taken (said loudly by the callers)
    double front_end_seconds = 0.0;     ///< descriptors, detection, verification, rejection
    double back_end_seconds = 0.0;      ///< baselines, RBCD, certificate
};

/// Progress through the pipeline: stage name and fraction done in [0, 1].
using MissionProgress = std::function<void(const std::string& stage, double fraction)>;

/// Joint graph: per robot the odometry chain (i -> i+1 from consecutive odometry poses), then
/// the loop closures; global index = robot offset + keyframe index, robots contiguous; ids set.
slam::PoseGraph BuildJointGraph(const std::vector<std::vector<Eigen::Isometry3d>>& odometry,
                                const std::vector<slam::LoopClosure>& loops,
                                const EdgeNoiseConfig& noise);

/// Joint graph from edges as a solver holds them (odometry and loops, each with its own weights,
/// e.g. the actor graph's SolverState::OwnEdges of every robot): robot r has poses[r] poses,
/// global index = robot offset + keyframe index; same-robot consecutive edges marked known
/// inliers; ids set. Edges whose ends are out of range are dropped.
slam::PoseGraph GraphFromEdges(const std::vector<int>& poses,
                               const std::vector<slam::LoopClosure>& edges);

/// Splits 3 x 4n poses into per-robot trajectories with the keyframes' stamps.
std::vector<slam::Trajectory> SplitTrajectories(
    const slam::PoseGraph& graph, const slam::PoseMatrix& poses,
    const std::vector<std::vector<slam::Keyframe>>& robots);

/// Certified RBCD on the joint graph (one block per robot): chordal initialisation lifted to
/// rank r, RBCD, certificate, saddle escape at rank r+1 while not certified (Riemannian
/// staircase), rounding, anchoring in pose 0's frame.
JointSolution SolveCertifiedJoint(const slam::PoseGraph& graph, const MissionSolverConfig& config);

/// Local search from an initial guess (3 x 4n): Levenberg-Marquardt (slam::SolveLm) on the
/// same objective, which stops at the nearest critical point; then the certificate at rank 3
/// says whether that point is the global optimum. Poses anchored (pose 0 = identity).
LocalSearchRun LocalSearchJoint(const slam::PoseGraph& graph, const slam::PoseMatrix& initial,
                                const MissionSolverConfig& config);

/// The pipeline after its front end, on `graph` (robots contiguous, as BuildJointGraph or
/// GraphFromEdges give it) with the accepted `loops` in discovery order: odometry, one-time
/// alignment, local search from odometry and from the alignment (each certified), and, when
/// `certified_rbcd`, certified RBCD (else `solution` and `certified` stay empty). Throws
/// std::runtime_error when some robot is joined to robot 0 by no chain of inter-robot loops.
MissionResult SolveMissionGraph(const std::vector<std::vector<slam::Keyframe>>& robots,
                                std::vector<slam::LoopClosure> loops, slam::PoseGraph graph,
                                const MissionConfig& config, bool certified_rbcd,
                                const MissionProgress& progress = {});

/// Runs the whole pipeline on keyframes (`robots[k][i]`, clouds needed unless the loop source
/// is ground truth). Throws std::runtime_error when some robot is joined to robot 0 by no
/// chain of inter-robot loops (the joint graph is disconnected). `truth` (T_world_sensor per robot
/// and keyframe) is used only by the ground-truth loop fallback; pass {} otherwise.
MissionResult RunMission(const std::vector<std::vector<slam::Keyframe>>& robots,
                         const std::vector<std::vector<Eigen::Isometry3d>>& truth,
                         const MissionConfig& config, const MissionProgress& progress = {});

}  // namespace certislam::certify
