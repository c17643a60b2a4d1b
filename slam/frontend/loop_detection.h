// Loop detection: Scan Context candidates across and within robots,
// verification by registration seeded with the Scan Context yaw, pairwise-consistency outlier
// rejection; and the loud ground-truth fallback used only when a front-end piece is missing.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "slam/core/keyframe.h"
#include "slam/core/loop_closure.h"
#include "slam/frontend/scan_context.h"

namespace certislam::slam {

/// Where loop closures come from.
enum class LoopSource {
    kFrontEnd,     ///< Scan Context + registration + outlier rejection (the real pipeline)
    kGroundTruth,  ///< fallback: pairs near in truth, relative pose from truth plus noise
};

/// Settings of loop detection.
struct LoopDetectionConfig {
    LoopSource source = LoopSource::kFrontEnd;  ///< the real front end unless asked otherwise
    ScanContextConfig scan_context;             ///< descriptor (20 x 60, 80 m)
    int ring_key_candidates = 5;        ///< ring-key nearest neighbours checked per query, >= 1
    double max_sc_distance = 0.2;       ///< Scan Context distance accepting a candidate, (0, 1]
    bool intra_robot = true;            ///< also look for revisits within one robot
    int min_intra_gap = 40;             ///< keyframes between an intra-robot pair, >= 1
    int query_stride = 1;               ///< every robot queries every k-th keyframe, >= 1
    double max_rmse_m = 0.3;            ///< registration: accept below this inlier RMSE, > 0
    double voxel_m = 0.4;               ///< registration downsampling, > 0
    bool reject_outliers = true;        ///< pairwise consistency (PCM) over the verified loops
    double pcm_chi2_threshold = 16.81;  ///< PCM: chi-square 6 dof at 99 %, > 0
    // Ground-truth fallback (LoopSource::kGroundTruth):
    double gt_max_distance_m = 3.0;  ///< pair keyframes closer than this in truth, > 0
    double gt_noise_t_m = 0.05;      ///< std of the translation noise added, >= 0
    double gt_noise_r_rad = 0.002;   ///< std of the rotation noise added, >= 0
    std::uint64_t seed = 7;          ///< noise seed of the fallback

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// A Scan Context candidate before verification.
struct LoopCandidate {
    PoseId query;              ///< the keyframe that searched
    PoseId match;              ///< the stored keyframe it matched
    double sc_distance = 1.0;  ///< Scan Context distance
    double yaw_rad = 0.0;      ///< yaw of query in match's frame implied by the column shift
};

/// Counts of the loop stage (also what crosses robot boundaries, in bytes).
struct LoopDetectionStats {
    int descriptors = 0;                     ///< descriptors computed
    int candidates = 0;                      ///< Scan Context candidates below max_sc_distance
    int verified = 0;                        ///< candidates registration accepted
    int rejected_registration = 0;           ///< candidates registration rejected
    int rejected_outliers = 0;               ///< verified loops PCM rejected
    int inter_robot = 0;                     ///< accepted inter-robot loops
    int intra_robot = 0;                     ///< accepted intra-robot loops
    std::int64_t descriptor_bytes_sent = 0;  ///< descriptors sent to peers (serialized size)
    std::int64_t cloud_bytes_sent = 0;       ///< clouds of inter-robot candidates sent to peers
    std::int64_t loop_bytes_sent = 0;        ///< inter-robot loop closures sent to the owner
};

/// The loop stage's output.
struct LoopDetectionResult {
    std::vector<LoopClosure> loops;     ///< accepted, in discovery order
    LoopDetectionStats stats;           ///< counts
    std::vector<std::string> warnings;  ///< every fallback taken, in words
};

/// Scan Context candidates: for each robot's keyframe (in stamp order over the team) the best
/// of its ring-key nearest neighbours among keyframes already seen of other robots, and of its
/// own robot at least min_intra_gap keyframes back; kept below max_sc_distance.
std::vector<LoopCandidate> DetectCandidates(
    const std::vector<std::vector<ScanContext>>& descriptors,
    const std::vector<std::vector<Keyframe>>& robots, const LoopDetectionConfig& config);

/// Loop closures from ground truth: for each robot's keyframe (every 2nd) the nearest keyframe
/// of the other robots (and its own, min_intra_gap back) within gt_max_distance_m, with the
/// true relative pose perturbed by the configured noise. Only for the loud fallback and tests.
std::vector<LoopClosure> GroundTruthLoops(const std::vector<std::vector<Eigen::Isometry3d>>& truth,
                                          const LoopDetectionConfig& config);

/// Runs the loop stage on keyframes; `truth` is used only by the ground-truth fallback.
LoopDetectionResult DetectLoops(const std::vector<std::vector<Keyframe>>& robots,
                                const std::vector<std::vector<Eigen::Isometry3d>>& truth,
                                const LoopDetectionConfig& config);

}  // namespace certislam::slam
