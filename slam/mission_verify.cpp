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
        }
    }
    result.stats.candidates =
        static_cast<int>(DetectCandidates(descriptors, robots, config).size());
    return result;
}

}  // namespace certislam::slam
