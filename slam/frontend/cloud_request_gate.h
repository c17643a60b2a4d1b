// Which Scan Context candidates are worth fetching a peer's cloud for: a stricter distance
// pre-gate, and one request per place (per robot pair) until a registration there fails.
#pragma once

#include <vector>

#include "slam/frontend/loop_detection.h"

namespace certislam::slam {

/// Settings of the cloud-request gate.
struct CloudRequestGateConfig {
    double max_sc_distance = 0.2;  ///< request only below this Scan Context distance, (0, 1]
    int place_window = 10;         ///< keyframes (about 1 m apart) that make one place, >= 0; a
                                   ///< candidate within the window of an admitted request on both
                                   ///< robots is skipped (0: every candidate is requested once)

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// Streaming gate over inter-robot candidates (intra-robot ones need no cloud and always pass).
class CloudRequestGate {
  public:
    /// Validates `config` (throws std::invalid_argument).
    explicit CloudRequestGate(const CloudRequestGateConfig& config = {});

    /// What to do about a candidate.
    enum class Decision {
        kSkip,      ///< above the distance gate, or its place already has an open request
        kRegister,  ///< register it with a cloud at hand (own robot's, or fetched before)
        kFetch,     ///< request the match's cloud from its robot, then register
    };

    /// Decides on `candidate` and records an admitted request.
    Decision Admit(const LoopCandidate& candidate);

    /// The registration of an admitted candidate failed: its place is open again.
    void Failed(const LoopCandidate& candidate);

  private:
    CloudRequestGateConfig config_;
    std::vector<LoopCandidate> admitted_;          // open requests, in admission order
    std::vector<std::pair<int, PoseId>> fetched_;  // (querying robot, match) clouds at hand
};

}  // namespace certislam::slam
