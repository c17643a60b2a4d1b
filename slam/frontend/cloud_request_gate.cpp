// One cloud request per place and robot pair; a failed registration reopens the place.
#include "slam/frontend/cloud_request_gate.h"

#include <algorithm>
#include <cstdlib>
#include <stdexcept>
#include <string>

namespace certislam::slam {
namespace {

bool SamePlace(const LoopCandidate& a, const LoopCandidate& b, int window) {
    return a.query.robot == b.query.robot && a.match.robot == b.match.robot &&
           std::abs(a.query.index - b.query.index) <= window &&
           std::abs(a.match.index - b.match.index) <= window;
}

}  // namespace

void CloudRequestGateConfig::Validate() const {
    if (!(max_sc_distance > 0.0 && max_sc_distance <= 1.0)) {
        throw std::invalid_argument("CloudRequestGateConfig.max_sc_distance = " +
                                    std::to_string(max_sc_distance) + ": must be in (0, 1]");
    }
    if (place_window < 0) {
        throw std::invalid_argument("CloudRequestGateConfig.place_window = " +
                                    std::to_string(place_window) + ": must be >= 0");
    }
}

CloudRequestGate::CloudRequestGate(const CloudRequestGateConfig& config) : config_(config) {
    config_.Validate();
}

CloudRequestGate::Decision CloudRequestGate::Admit(const LoopCandidate& candidate) {
    if (candidate.query.robot == candidate.match.robot) return Decision::kRegister;
    if (!(candidate.sc_distance < config_.max_sc_distance)) return Decision::kSkip;
    const bool seen = std::any_of(admitted_.begin(), admitted_.end(), [&](const auto& a) {
        return SamePlace(a, candidate, config_.place_window);
    });
    if (seen) return Decision::kSkip;
    admitted_.push_back(candidate);
    const std::pair<int, PoseId> key(candidate.query.robot, candidate.match);
    if (std::find(fetched_.begin(), fetched_.end(), key) != fetched_.end()) {
        return Decision::kRegister;
    }
    fetched_.push_back(key);
    return Decision::kFetch;
}

void CloudRequestGate::Failed(const LoopCandidate& candidate) {
    std::erase_if(admitted_, [&](const LoopCandidate& a) {
        return a.query == candidate.query && a.match == candidate.match;
    });
}

}  // namespace certislam::slam
