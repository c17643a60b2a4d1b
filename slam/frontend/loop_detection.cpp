// Loop-closure stage of the mission pipeline (Scan Context candidates, ground-truth fallback).
#include "slam/frontend/loop_detection.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <utility>

#include "slam/frontend/loop_verification.h"

namespace certislam::slam {
namespace {

void Require(bool ok, const std::string& field, double value, const std::string& rule) {
    if (!ok) {
        throw std::invalid_argument("LoopDetectionConfig." + field + " = " + std::to_string(value) +
                                    ": " + rule);
    }
}

/// A keyframe in the team's stamp order.
struct Visit {
    std::int64_t stamp_ns;
    PoseId id;
};

std::vector<Visit> StampOrder(const std::vector<std::vector<Keyframe>>& robots) {
    std::vector<Visit> order;
    for (size_t r = 0; r < robots.size(); ++r) {
        for (size_t i = 0; i < robots[r].size(); ++i) {
            order.push_back({robots[r][i].stamp_ns, {static_cast<int>(r), static_cast<int>(i)}});
        }
    }
    std::stable_sort(order.begin(), order.end(),
                     [](const Visit& a, const Visit& b) { return a.stamp_ns < b.stamp_ns; });
    return order;
}

Eigen::Isometry3d Perturbation(std::mt19937_64& rng, double sigma_t, double sigma_r) {
    std::normal_distribution<double> normal(0.0, 1.0);
    const Eigen::Vector3d w(normal(rng), normal(rng), normal(rng));
    const Eigen::Vector3d v(normal(rng), normal(rng), normal(rng));
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    if (sigma_r > 0) {
        T.linear() = Eigen::AngleAxisd(sigma_r * w.norm(), w.normalized()).toRotationMatrix();
    }
    T.translation() = sigma_t * v;
    return T;
}

}  // namespace

void LoopDetectionConfig::Validate() const {
    scan_context.Validate();
    Require(ring_key_candidates >= 1, "ring_key_candidates", ring_key_candidates, "must be >= 1");
    Require(max_sc_distance > 0 && max_sc_distance <= 1, "max_sc_distance", max_sc_distance,
            "must be in (0, 1]");
    Require(min_intra_gap >= 1, "min_intra_gap", min_intra_gap, "must be >= 1");
    Require(query_stride >= 1, "query_stride", query_stride, "must be >= 1");
    Require(max_rmse_m > 0, "max_rmse_m", max_rmse_m, "must be > 0");
    Require(voxel_m > 0, "voxel_m", voxel_m, "must be > 0");
    Require(pcm_chi2_threshold > 0, "pcm_chi2_threshold", pcm_chi2_threshold, "must be > 0");
    Require(gt_max_distance_m > 0, "gt_max_distance_m", gt_max_distance_m, "must be > 0");
    Require(gt_noise_t_m >= 0, "gt_noise_t_m", gt_noise_t_m, "must be >= 0");
    Require(gt_noise_r_rad >= 0, "gt_noise_r_rad", gt_noise_r_rad, "must be >= 0");
}

std::vector<LoopCandidate> DetectCandidates(
    const std::vector<std::vector<ScanContext>>& descriptors,
    const std::vector<std::vector<Keyframe>>& robots, const LoopDetectionConfig& config) {
    // Brute-force ring-key search: a few hundred keyframes per mission make it cheaper than
    // maintaining a tree here; the loop-matcher actor uses the front end's database.
    std::vector<LoopCandidate> candidates;
    std::vector<PoseId> seen;
    std::vector<std::pair<float, PoseId>> nearest;
    for (const Visit& visit : StampOrder(robots)) {
        const ScanContext& query = descriptors[visit.id.robot][visit.id.index];
        // Every robot's every k-th keyframe, as the loop-matcher actor's stride.
        if (visit.id.index % config.query_stride == 0) {
            nearest.clear();
            for (const PoseId& id : seen) {
                if (id.robot == visit.id.robot &&
                    (!config.intra_robot || visit.id.index - id.index < config.min_intra_gap)) {
                    continue;
                }
                const auto& key = descriptors[id.robot][id.index].ring_key;
                nearest.emplace_back((key - query.ring_key).squaredNorm(), id);
            }
            const size_t k = std::min(nearest.size(), size_t(config.ring_key_candidates));
            std::partial_sort(nearest.begin(), nearest.begin() + static_cast<long>(k),
                              nearest.end(),
                              [](const auto& a, const auto& b) { return a.first < b.first; });
            LoopCandidate best;
            for (size_t c = 0; c < k; ++c) {
                const PoseId id = nearest[c].second;
                const auto match = ScanContextDistanceFast(query, descriptors[id.robot][id.index],
                                                           config.scan_context);
                if (match.distance < best.sc_distance) {
                    best = {visit.id, id, match.distance, match.yaw_rad};
                }
            }
            if (best.sc_distance < config.max_sc_distance) candidates.push_back(best);
        }
        seen.push_back(visit.id);
    }
    return candidates;
}

std::vector<LoopClosure> GroundTruthLoops(const std::vector<std::vector<Eigen::Isometry3d>>& truth,
                                          const LoopDetectionConfig& config) {
    std::mt19937_64 rng(config.seed);
    std::vector<LoopClosure> loops;
    for (size_t rb = 0; rb < truth.size(); ++rb) {
        for (size_t ib = 0; ib < truth[rb].size(); ib += 2) {
            const Eigen::Vector3d p = truth[rb][ib].translation();
            double best = config.gt_max_distance_m;
            std::optional<PoseId> match;
            for (size_t ra = 0; ra <= rb; ++ra) {
                const size_t end = ra == rb ? (ib >= size_t(config.min_intra_gap)
                                                   ? ib - size_t(config.min_intra_gap) + 1
                                                   : 0)
                                            : truth[ra].size();
                if (ra == rb && !config.intra_robot) continue;
                for (size_t ia = 0; ia < end; ++ia) {
                    const double dist = (truth[ra][ia].translation() - p).norm();
                    if (dist < best) {
                        best = dist;
                        match = PoseId{static_cast<int>(ra), static_cast<int>(ia)};
                    }
                }
            }
            if (!match) continue;
            LoopClosure loop;
            loop.a = *match;
            loop.b = {static_cast<int>(rb), static_cast<int>(ib)};
            loop.T_a_b = truth[match->robot][match->index].inverse() * truth[rb][ib] *
                         Perturbation(rng, config.gt_noise_t_m, config.gt_noise_r_rad);
            loop.sc_distance = 0.0;
            loop.from_ground_truth = true;
            loops.push_back(loop);
        }
    }
    return loops;
}

LoopDetectionResult DetectLoops(const std::vector<std::vector<Keyframe>>& robots,
                                const std::vector<std::vector<Eigen::Isometry3d>>& truth,
                                const LoopDetectionConfig& config) {
    config.Validate();
    LoopDetectionResult result;
    LoopSource source = config.source;
    if (source == LoopSource::kFrontEnd && !FrontEndVerificationAvailable()) {
        result.warnings.push_back(
            "FALLBACK: registration/outlier rejection not available in this build; loop "
            "closures are GROUND-TRUTH pairs with added noise, not detected ones");
        source = LoopSource::kGroundTruth;
    }
    if (source == LoopSource::kGroundTruth) {
        if (config.source == LoopSource::kGroundTruth) {
            result.warnings.push_back(
                "loop closures are GROUND-TRUTH pairs with added noise (asked for)");
        }
        if (truth.size() != robots.size()) {
            throw std::invalid_argument("ground-truth loop closures need the truth of every robot");
        }
        const bool have_clouds = !robots.empty() && !robots[0].empty() && robots[0][0].cloud;
        if (have_clouds) {
            // Descriptors and Scan Context candidates are still real: their counts and bytes.
            result.stats = CandidateStats(robots, config);
        }
        result.loops = GroundTruthLoops(truth, config);
    } else {
        result = VerifyAndReject(robots, config);
    }
    for (const auto& loop : result.loops) {
        (loop.inter_robot() ? result.stats.inter_robot : result.stats.intra_robot) += 1;
    }
    return result;
}

}  // namespace certislam::slam
