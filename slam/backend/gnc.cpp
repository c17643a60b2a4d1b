// GNC-TLS (Yang, Antonante, Tzoumas, Carlone, RA-L 2020, Sec. III and Prop. 4).
#include "slam/backend/gnc.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <stdexcept>
#include <string>

#include "slam/core/check.h"

namespace certislam::slam {
namespace {

void Require(bool ok, const std::string& field, double value, const std::string& rule) {
    if (!ok) {
        throw std::invalid_argument("GncConfig." + field + " = " + std::to_string(value) +
                                    ": must be " + rule);
    }
}

/// TLS weight for squared residual r2 at mu (Prop. 4): 1 inside, 0 outside, a ramp between.
double TlsWeight(double r2, double c2, double mu) {
    if (r2 >= (mu + 1.0) / mu * c2) return 0.0;
    if (r2 <= mu / (mu + 1.0) * c2) return 1.0;
    return std::sqrt(c2 * mu * (mu + 1.0) / r2) - mu;
}

/// Sets weights; returns true when every free weight is binary within the tolerance.
bool UpdateWeights(const std::vector<double>& r2, double c2, double mu, double tolerance,
                   PoseGraph* graph) {
    bool binary = true;
    for (size_t e = 0; e < r2.size(); ++e) {
        auto& edge = graph->edges[e];
        if (edge.is_known_inlier) continue;
        edge.weight = TlsWeight(r2[e], c2, mu);
        binary = binary && (edge.weight < tolerance || edge.weight > 1.0 - tolerance);
    }
    return binary;
}

/// True for an odometry edge: consecutive keyframes of one robot (either direction). Poses
/// without ids are numbered along one trajectory, so consecutive global indices.
bool IsOdometry(const PoseGraph& graph, const RelativePoseMeasurement& e) {
    const auto n = static_cast<int>(graph.ids.size());
    if (e.i >= n || e.j >= n) return std::abs(e.i - e.j) == 1;
    const PoseId& a = graph.ids[static_cast<size_t>(e.i)];
    const PoseId& b = graph.ids[static_cast<size_t>(e.j)];
    return a.robot == b.robot && std::abs(a.index - b.index) == 1;
}

/// Weights within binary_tolerance of 0 still let a gross outlier (r^2 ~ 1e7) pull the estimate.
/// Snaps the weights to 0/1 (keep_weight), re-solves, then re-applies the TLS rule (weight 1 iff
/// r^2 <= c^2, the mu -> infinity limit of Prop. 4) until the inlier set is a fixed point.
void Refine(const Partition& partition, double c2, const GncConfig& config, PoseGraph* weighted,
            RbcdResult* solved, GncResult* result) {
    for (int k = 0; k < config.max_iterations; ++k) {
        const std::vector<double> r2 = EdgeSquaredResiduals(*weighted, solved->X);
        bool changed = false;
        for (size_t e = 0; e < r2.size(); ++e) {
            auto& edge = weighted->edges[e];
            if (edge.is_known_inlier) continue;
            const bool keep = k == 0 ? edge.weight >= config.keep_weight : r2[e] <= c2;
            changed = changed || (keep ? 1.0 : 0.0) != edge.weight;
            edge.weight = keep ? 1.0 : 0.0;
        }
        if (!changed) return;
        *solved = SolveRbcd(*weighted, partition, solved->X, config.rbcd);
        result->rbcd_iterations += solved->iterations;
    }
}

/// The TLS inlier rule after a trial: every free edge of weight 1 has r^2 <= c^2 at X, and no
/// known inlier (odometry) was bent beyond max(c^2, its r^2 before): an outlier must not be
/// absorbed by distorting the edges GNC cannot reject.
bool TrialConsistent(const PoseGraph& weighted, const std::vector<double>& before,
                     const Eigen::MatrixXd& X, double c2) {
    const std::vector<double> r2 = EdgeSquaredResiduals(weighted, X);
    for (size_t e = 0; e < r2.size(); ++e) {
        const auto& edge = weighted.edges[e];
        if (edge.weight != 1.0) continue;
        if (r2[e] > (edge.is_known_inlier ? std::max(c2, before[e]) : c2)) return false;
    }
    return true;
}

/// GNC started near odometry can reject genuine loops: their residual is large only while the
/// kept graph lacks them (drift). Each rejected edge, smallest current residual first, is put
/// back and the problem re-solved; it stays when TrialConsistent holds at the new solution (a
/// gross outlier keeps a large residual however the poses move).
void Reinstate(const Partition& partition, double c2, const GncConfig& config, PoseGraph* weighted,
               RbcdResult* solved, GncResult* result) {
    std::vector<bool> tried(weighted->edges.size(), false);
    for (int failures = 0; failures < config.max_reinstatement_failures;) {
        const std::vector<double> r2 = EdgeSquaredResiduals(*weighted, solved->X);
        std::optional<size_t> next;
        for (size_t e = 0; e < r2.size(); ++e) {
            const auto& edge = weighted->edges[e];
            if (edge.is_known_inlier || edge.weight != 0.0 || tried[e]) continue;
            if (!next || r2[e] < r2[*next]) next = e;
        }
        if (!next) return;
        tried[*next] = true;
        weighted->edges[*next].weight = 1.0;
        RbcdResult trial = SolveRbcd(*weighted, partition, solved->X, config.rbcd);
        result->rbcd_iterations += trial.iterations;
        if (TrialConsistent(*weighted, r2, trial.X, c2)) {
            *solved = std::move(trial);
            ++result->reinstated;
            failures = 0;
        } else {
            weighted->edges[*next].weight = 0.0;
            ++failures;
        }
    }
}

}  // namespace

void GncConfig::Validate() const {
    Require(threshold > 0.0, "threshold", threshold, "> 0");
    Require(mu_growth > 1.0, "mu_growth", mu_growth, "> 1");
    Require(max_iterations > 0, "max_iterations", max_iterations, "> 0");
    Require(binary_tolerance > 0.0 && binary_tolerance < 0.5, "binary_tolerance", binary_tolerance,
            "in (0, 0.5)");
    Require(keep_weight > 0.0 && keep_weight <= 1.0, "keep_weight", keep_weight, "in (0, 1]");
    Require(max_reinstatement_failures >= 0, "max_reinstatement_failures",
            max_reinstatement_failures, ">= 0");
    rbcd.Validate();
}

std::vector<double> EdgeSquaredResiduals(const PoseGraph& graph, const Eigen::MatrixXd& X) {
    const int d = graph.d;
    std::vector<double> r2;
    r2.reserve(graph.edges.size());
    for (const auto& e : graph.edges) {
        const auto Yi = X.middleCols(BlockColumn(e.i, d), d);
        const auto Yj = X.middleCols(BlockColumn(e.j, d), d);
        const auto pi = X.col(BlockColumn(e.i, d) + d);
        const auto pj = X.col(BlockColumn(e.j, d) + d);
        r2.push_back(e.kappa * (Yj - Yi * e.R).squaredNorm() +
                     e.tau * (pj - pi - Yi * e.t).squaredNorm());
    }
    return r2;
}

GncResult SolveGnc(const PoseGraph& graph, const Partition& partition, const Eigen::MatrixXd& X0,
                   const GncConfig& config) {
    config.Validate();
    const auto start = std::chrono::steady_clock::now();
    const double c2 = config.threshold * config.threshold;
    PoseGraph weighted = graph;
    for (auto& e : weighted.edges) {
        e.weight = 1.0;
        // Odometry is held at weight 1 (as dpgo's GNC does): the kept graph stays connected,
        // so GNC can never reject every edge and leave a zero problem behind.
        if (config.keep_odometry && IsOdometry(graph, e)) e.is_known_inlier = true;
    }
    GncResult result;
    RbcdResult solved = SolveRbcd(weighted, partition, X0, config.rbcd);
    result.rbcd_iterations = solved.iterations;
    std::vector<double> r2 = EdgeSquaredResiduals(weighted, solved.X);
    double max_r2 = 0.0;
    for (size_t e = 0; e < r2.size(); ++e) {
        if (!weighted.edges[e].is_known_inlier) max_r2 = std::max(max_r2, r2[e]);
    }
    double mu = max_r2 > c2 ? c2 / std::max(2.0 * max_r2 - c2, 1e-12 * c2) : 0.0;
    result.status = GncResult::Status::kNoOutliers;
    for (int k = 0; mu > 0.0 && k < config.max_iterations; ++k) {
        result.iterations = k + 1;
        const bool binary = UpdateWeights(r2, c2, mu, config.binary_tolerance, &weighted);
        solved = SolveRbcd(weighted, partition, solved.X, config.rbcd);
        result.rbcd_iterations += solved.iterations;
        r2 = EdgeSquaredResiduals(weighted, solved.X);
        result.status = GncResult::Status::kMaxIterations;
        if (binary) {
            result.status = GncResult::Status::kConverged;
            break;
        }
        mu *= config.mu_growth;
    }
    if (mu > 0.0) {
        Refine(partition, c2, config, &weighted, &solved, &result);
        Reinstate(partition, c2, config, &weighted, &solved, &result);
    }
    result.final_mu = mu;
    result.X = solved.X;
    result.kept = graph;
    result.kept.edges.clear();
    for (size_t e = 0; e < graph.edges.size(); ++e) {
        result.weights.push_back(weighted.edges[e].weight);
        result.inlier.push_back(weighted.edges[e].is_known_inlier ||
                                weighted.edges[e].weight >= config.keep_weight);
        if (!result.inlier.back()) continue;
        result.kept.edges.push_back(graph.edges[e]);
        result.kept.edges.back().weight = 1.0;
    }
    result.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return result;
}

}  // namespace certislam::slam
