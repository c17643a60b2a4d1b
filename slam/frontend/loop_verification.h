// Loop verification: descriptors, candidates, registration seeded
// by the Scan Context yaw, pairwise-consistency rejection (adapters over the front end's API).
#pragma once

#include <vector>

#include "slam/frontend/loop_detection.h"
#include "slam/frontend/registration.h"

namespace certislam::slam {

/// True when this build has the registration and outlier-rejection pieces the real loop stage
/// needs; otherwise DetectLoops falls back to ground truth, loudly.
bool FrontEndVerificationAvailable();

/// A loop closure registration accepted, with the full information of its relative pose.
struct VerifiedLoop {
    LoopClosure loop;                                     ///< a = match, b = query
    Information6 information = Information6::Identity();  ///< of loop.T_a_b (registration's)
};

/// Registers each candidate's query cloud onto its match's, seeded by the Scan Context yaw;
/// keeps those registration accepts with inlier RMSE <= max_rmse_m. Counts verified/rejected
/// and the cloud bytes of inter-robot candidates in *stats.
std::vector<VerifiedLoop> VerifyCandidates(const std::vector<std::vector<Keyframe>>& robots,
                                           const std::vector<LoopCandidate>& candidates,
                                           const LoopDetectionConfig& config,
                                           LoopDetectionStats* stats);

/// PCM over the verified loops with the keyframes' odometry (slam/pcm.h); counts rejections.
std::vector<LoopClosure> RejectOutliers(const std::vector<std::vector<Keyframe>>& robots,
                                        const std::vector<VerifiedLoop>& verified,
                                        const LoopDetectionConfig& config,
                                        LoopDetectionStats* stats);

/// Descriptors and Scan Context candidates only (no registration): the counts and bytes the
/// ground-truth fallback still reports.
LoopDetectionStats CandidateStats(const std::vector<std::vector<Keyframe>>& robots,
                                  const LoopDetectionConfig& config);

/// Descriptors, candidates, verification and outlier rejection on real clouds.
LoopDetectionResult VerifyAndReject(const std::vector<std::vector<Keyframe>>& robots,
                                    const LoopDetectionConfig& config);

}  // namespace certislam::slam
