// SolvePoseGraph: chordal (or odometry) start, GNC-TLS when robust, the RBCD staircase (or LM),
// SE-Sync rounding, and the certificate's bound for the rounded poses.
#include "certify/pose_graph_solver.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "slam/backend/chordal.h"
#include "slam/backend/connection_laplacian.h"
#include "slam/backend/rounding.h"
#include "slam/core/partition.h"

namespace certislam::certify {
namespace {

using Clock = std::chrono::steady_clock;
using Result = PoseGraphSolverResult;

/// The start of the certified solve on GNC's inlier graph: GNC's last iterate or the inlier
/// graph's own chordal initialisation, whichever costs less on it. GNC's iterate was shaped by the
/// outliers' early weights and can sit far from the inlier graph's optimum (RBCD can stall there).
Eigen::MatrixXd InlierStart(const slam::GncResult& gnc, int rank) {
    const auto Q = slam::ConnectionLaplacian(gnc.kept);
    try {
        Eigen::MatrixXd chordal = slam::LiftToRank(slam::ChordalInitialization(gnc.kept), rank);
        if (chordal.allFinite() && slam::LiftedCost(Q, chordal) < slam::LiftedCost(Q, gnc.X)) {
            return chordal;
        }
    } catch (const std::exception&) {
        // No chordal start (e.g. a kept graph in several pieces): GNC's iterate it is.
    }
    return gnc.X;
}

double Since(Clock::time_point start) {
    return std::chrono::duration<double>(Clock::now() - start).count();
}

// The certificate's lower bound applies to any estimate of the same graph: the bound of the
// rounded poses is their cost minus it, and "certified" needs that bound within the limit too.
void SetCertificate(const CertificateResult& certificate, double max_relative_bound,
                    Result* result) {
    result->certificate = certificate;
    result->status = certificate.status;
    result->reason = certificate.reason;
    result->has_bound = certificate.has_bound;
    if (!certificate.has_bound) return;
    result->lower_bound = certificate.lower_bound;
    result->suboptimality_bound = std::max(result->cost - certificate.lower_bound, 0.0);
    // Relative to the cost floored at f's rounding noise, as the certificate's own bound: rounded
    // poses of an f* = 0 graph (a tree, kitti_08) cost that noise, and f* >= 0 bounds their gap.
    const double scale = std::max(result->cost, certificate.objective_noise);
    result->relative_suboptimality_bound = scale > 0.0 ? result->suboptimality_bound / scale
                                                       : certificate.relative_suboptimality_bound;
    if (result->status == Result::Status::kCertified &&
        result->cost > certificate.objective_noise &&
        result->relative_suboptimality_bound > max_relative_bound) {
        result->status = Result::Status::kInconclusive;
        char text[128];
        std::snprintf(text, sizeof(text),
                      "the rounded poses' relative suboptimality bound %.3g exceeds %.3g",
                      result->relative_suboptimality_bound, max_relative_bound);
        result->reason = text;
    }
}

slam::Partition MakePartition(const slam::PoseGraph& graph, int robots) {
    return robots == 0 ? slam::PartitionFromIds(graph) : slam::ContiguousPartition(graph.n, robots);
}

void SolveWithLm(const slam::PoseGraph& graph, const PoseGraphSolverConfig& config,
                 const PoseGraphSolverProgress& progress, Clock::time_point start, Result* result) {
    const slam::PoseMatrix initial = slam::OdometryInitialization(graph);
    const slam::LmResult lm = slam::SolveLm(graph, initial, config.lm);
    if (progress) progress("lm", graph.d, lm.cost, 0.0, Since(start));
    LocalSearchPolishConfig polish;
    polish.rbcd = config.lm_polish;
    polish.certificate = config.staircase.certificate;
    const LocalSearchCertificate judged = CertifyLocalSearch(graph, lm.poses, polish);
    result->poses = judged.poses;
    result->cost = judged.certificate.objective;
    result->local_search_cost = judged.input_cost;
    result->polish_iterations = judged.polish_iterations;
    result->iterations = lm.iterations;
    result->rank = graph.d;
    SetCertificate(judged.certificate, config.staircase.certificate.max_relative_bound, result);
    if (progress)
        progress("certify", graph.d, result->cost, result->certificate.gradient_norm, Since(start));
}

void SolveWithRbcd(const slam::PoseGraph& graph, const PoseGraphSolverConfig& config,
                   const PoseGraphSolverProgress& progress, Clock::time_point start,
                   Result* result) {
    const int d = graph.d;
    const int rank = config.rank == 0 ? d : config.rank;
    const slam::Partition partition = MakePartition(graph, config.robots);
    Eigen::MatrixXd X0 = slam::LiftToRank(slam::ChordalInitialization(graph), rank);
    if (progress)
        progress("chordal", rank, slam::LiftedCost(slam::ConnectionLaplacian(graph), X0), 0.0,
                 Since(start));
    if (config.robust) {
        const slam::GncResult gnc = slam::SolveGnc(graph, partition, X0, config.gnc);
        result->solved_graph = gnc.kept;
        result->gnc_iterations = gnc.iterations;
        result->gnc_reinstated = gnc.reinstated;
        for (size_t e = 0; e < gnc.inlier.size(); ++e) {
            if (!gnc.inlier[e]) result->rejected_edges.push_back(static_cast<int>(e));
        }
        X0 = InlierStart(gnc, rank);
        if (progress)
            progress("gnc", rank, slam::LiftedCost(slam::ConnectionLaplacian(gnc.kept), X0), 0.0,
                     Since(start));
    }
    const slam::PoseGraph& solved = result->solved_graph;
    const StaircaseResult stairs =
        SolveCertified(solved, partition, X0, config.staircase, [&](const StaircaseProgress& p) {
            if (progress) progress(p.stage, p.rank, p.cost, p.grad_norm, Since(start));
        });
    result->poses = slam::RoundSolution(solved, stairs.X);
    result->cost = slam::Objective(solved, result->poses);
    result->rank = stairs.rank;
    result->iterations = stairs.iterations;
    result->escapes = stairs.escapes;
    SetCertificate(stairs.certificate, config.staircase.certificate.max_relative_bound, result);
}

}  // namespace

void PoseGraphSolverConfig::Validate() const {
    if (robots < 0) {
        throw std::invalid_argument("PoseGraphSolverConfig.robots = " + std::to_string(robots) +
                                    ": must be >= 0 (0: the graph's own robots)");
    }
    if (rank < 0) {
        throw std::invalid_argument("PoseGraphSolverConfig.rank = " + std::to_string(rank) +
                                    ": must be 0 (the dimension d) or >= d");
    }
    if (robust && method == Method::kLm) {
        throw std::invalid_argument(
            "PoseGraphSolverConfig.robust = true: only with method rbcd (GNC runs on RBCD)");
    }
    staircase.Validate();
    lm.Validate();
    lm_polish.Validate();
    gnc.Validate();
}

Result SolvePoseGraph(const slam::PoseGraph& graph, const PoseGraphSolverConfig& config,
                      const PoseGraphSolverProgress& progress) {
    config.Validate();
    if (config.rank != 0 && config.rank < graph.d) {
        throw std::invalid_argument("PoseGraphSolverConfig.rank = " + std::to_string(config.rank) +
                                    ": must be >= d = " + std::to_string(graph.d));
    }
    if (config.robots > graph.n) {
        throw std::invalid_argument(
            "PoseGraphSolverConfig.robots = " + std::to_string(config.robots) +
            ": must be <= n = " + std::to_string(graph.n));
    }
    const auto start = Clock::now();
    Result result;
    result.solved_graph = graph;
    if (config.method == PoseGraphSolverConfig::Method::kLm) {
        SolveWithLm(graph, config, progress, start, &result);
    } else {
        SolveWithRbcd(graph, config, progress, start, &result);
    }
    result.edges_used = static_cast<int>(result.solved_graph.edges.size());
    result.seconds = Since(start);
    return result;
}

}  // namespace certislam::certify
