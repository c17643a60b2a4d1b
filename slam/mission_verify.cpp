// Verification and outlier rejection of Scan Context candidates (front-end adapters).
#include "slam/mission_verify.h"

namespace certislam::slam {

bool FrontEndVerificationAvailable() { return false; }

LoopDetectionResult VerifyAndReject(const std::vector<std::vector<Keyframe>>& robots,
                                    const LoopDetectionConfig& config) {
    LoopDetectionResult result;
    std::vector<std::vector<ScanContext>> descriptors(robots.size());
    for (size_t r = 0; r < robots.size(); ++r) {
        for (const auto& kf : robots[r]) {
            descriptors[r].push_back(MakeScanContext(*kf.cloud, config.scan_context));
            ++result.stats.descriptors;
            // Every descriptor goes to every peer (DESIGN.md: descriptors, not clouds).
            result.stats.descriptor_bytes_sent +=
                static_cast<std::int64_t>(SerializeScanContext(descriptors[r].back()).size()) *
                static_cast<std::int64_t>(robots.size() - 1);
        }
    }
    const auto candidates = DetectCandidates(descriptors, robots, config);
    result.stats.candidates = static_cast<int>(candidates.size());
    for (const auto& c : candidates) {
        // The querying robot asks the owner of the match for its cloud (float32 xyz).
        if (c.query.robot == c.match.robot) continue;
        result.stats.cloud_bytes_sent +=
            static_cast<std::int64_t>(12 * robots[c.match.robot][c.match.index].cloud->size());
    }
    return result;
}

}  // namespace certislam::slam
