// The verified part of the mission's loop stage: descriptors, candidates, registration seeded
// by the Scan Context yaw, pairwise-consistency rejection (adapters over the front end's API).
#pragma once

#include <vector>

#include "slam/mission_loops.h"

namespace certislam::slam {

/// True when this build has the registration and outlier-rejection pieces the real loop stage
/// needs; otherwise DetectLoops falls back to ground truth, loudly.
bool FrontEndVerificationAvailable();

/// Descriptors, candidates, verification and outlier rejection on real clouds.
LoopDetectionResult VerifyAndReject(const std::vector<std::vector<Keyframe>>& robots,
                                    const LoopDetectionConfig& config);

}  // namespace certislam::slam
