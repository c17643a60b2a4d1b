// Verification and outlier rejection of Scan Context candidates (front-end adapters): GICP
// seeded by the Scan Context yaw, fitness/RMSE/degeneracy gates, then PCM per robot pair.
#include "slam/frontend/loop_verification.h"

#include <algorithm>

#include "slam/frontend/downsample.h"
#include "slam/frontend/pcm.h"
#include "slam/frontend/registration.h"

namespace certislam::slam {
namespace {

RegistrationConfig RegistrationSettings(const LoopDetectionConfig& config) {
    RegistrationConfig registration;
    registration.voxel_m = config.voxel_m;
    registration.max_correspondence_m = 2.5 * config.voxel_m;
    registration.inlier_distance_m = std::max(registration.inlier_distance_m, config.voxel_m);
    return registration;
}

// Descriptors of every keyframe, with the bytes each robot sends to its peers.
std::vector<std::vector<ScanContext>> Describe(const std::vector<std::vector<Keyframe>>& robots,
                                               const LoopDetectionConfig& config,
                                               LoopDetectionStats* stats) {
    std::vector<std::vector<ScanContext>> descriptors(robots.size());
    for (size_t r = 0; r < robots.size(); ++r) {
        for (const auto& kf : robots[r]) {
            descriptors[r].push_back(MakeScanContext(*kf.cloud, config.scan_context));
            ++stats->descriptors;
            // Every descriptor goes to every peer (DESIGN.md: descriptors, not clouds).
            stats->descriptor_bytes_sent +=
                static_cast<std::int64_t>(SerializeScanContext(descriptors[r].back()).size()) *
                static_cast<std::int64_t>(robots.size() - 1);
        }
    }
    return descriptors;
}

// A candidate's cloud crosses robots downsampled to the registration voxel (float32 xyz).
std::int64_t SentCloudBytes(const PointCloud& cloud, const LoopDetectionConfig& config) {
    return static_cast<std::int64_t>(12 * VoxelDownsample(cloud, config.voxel_m).size());
}

}  // namespace

bool FrontEndVerificationAvailable() { return true; }

std::vector<VerifiedLoop> VerifyCandidates(const std::vector<std::vector<Keyframe>>& robots,
                                           const std::vector<LoopCandidate>& candidates,
                                           const LoopDetectionConfig& config,
                                           LoopDetectionStats* stats) {
    const RegistrationConfig registration = RegistrationSettings(config);
    std::vector<VerifiedLoop> verified;
    for (const auto& c : candidates) {
        const Keyframe& query = robots[c.query.robot][c.query.index];
        const Keyframe& match = robots[c.match.robot][c.match.index];
        if (c.query.robot != c.match.robot) {  // the querying robot asks for the match's cloud
            stats->cloud_bytes_sent += SentCloudBytes(*match.cloud, config);
        }
        const RegistrationResult r =
            RegisterScans(*query.cloud, *match.cloud, YawGuess(c.yaw_rad), registration);
        if (!r.accepted() || r.inlier_rmse_m > config.max_rmse_m) {
            ++stats->rejected_registration;
            continue;
        }
        ++stats->verified;
        VerifiedLoop v;
        v.loop.a = c.match;
        v.loop.b = c.query;
        v.loop.T_a_b = r.T_target_source;
        v.loop.kappa = r.kappa;
        v.loop.tau = r.tau;
        v.loop.sc_distance = c.sc_distance;
        v.loop.fitness = r.inlier_rmse_m * r.inlier_rmse_m;
        v.information = r.information;
        verified.push_back(v);
    }
    return verified;
}

std::vector<LoopClosure> RejectOutliers(const std::vector<std::vector<Keyframe>>& robots,
                                        const std::vector<VerifiedLoop>& verified,
                                        const LoopDetectionConfig& config,
                                        LoopDetectionStats* stats) {
    std::vector<std::vector<Eigen::Isometry3d>> odometry(robots.size());
    for (size_t r = 0; r < robots.size(); ++r) {
        for (const auto& kf : robots[r]) odometry[r].push_back(kf.T_odom_sensor);
    }
    std::vector<PcmMeasurement> measurements;
    measurements.reserve(verified.size());
    for (const auto& v : verified) {
        measurements.push_back({v.loop.a, v.loop.b, v.loop.T_a_b, v.information});
    }
    PcmConfig pcm;
    pcm.chi2_threshold = config.pcm_chi2_threshold;
    const PcmResult result = RejectOutliersPcm(measurements, odometry, pcm);
    std::vector<LoopClosure> kept;
    for (size_t k = 0; k < verified.size(); ++k) {
        if (result.inlier[k]) {
            kept.push_back(verified[k].loop);
        } else {
            ++stats->rejected_outliers;
        }
    }
    return kept;
}

LoopDetectionStats CandidateStats(const std::vector<std::vector<Keyframe>>& robots,
                                  const LoopDetectionConfig& config) {
    LoopDetectionStats stats;
    const auto descriptors = Describe(robots, config, &stats);
    const auto candidates = DetectCandidates(descriptors, robots, config);
    stats.candidates = static_cast<int>(candidates.size());
    for (const auto& c : candidates) {
        if (c.query.robot == c.match.robot) continue;
        stats.cloud_bytes_sent +=
            SentCloudBytes(*robots[c.match.robot][c.match.index].cloud, config);
    }
    return stats;
}

LoopDetectionResult VerifyAndReject(const std::vector<std::vector<Keyframe>>& robots,
                                    const LoopDetectionConfig& config) {
    LoopDetectionResult result;
    const auto descriptors = Describe(robots, config, &result.stats);
    const auto candidates = DetectCandidates(descriptors, robots, config);
    result.stats.candidates = static_cast<int>(candidates.size());
    const auto verified = VerifyCandidates(robots, candidates, config, &result.stats);
    if (config.reject_outliers) {
        result.loops = RejectOutliers(robots, verified, config, &result.stats);
    } else {
        for (const auto& v : verified) result.loops.push_back(v.loop);
    }
    for (const auto& loop : result.loops) {
        if (loop.inter_robot()) {
            result.stats.loop_bytes_sent += static_cast<std::int64_t>(sizeof(LoopClosure));
        }
    }
    return result;
}

}  // namespace certislam::slam
