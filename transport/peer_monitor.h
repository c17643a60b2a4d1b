// Liveness of peers from heartbeats: marks a peer dead after missed beats and alive again when
// heard. No sockets and no clock of its own: the actor runtime feeds it and ticks it.
#pragma once

#include <chrono>
#include <cstdint>
#include <map>
#include <optional>
#include <vector>

namespace certislam::transport {

/// Heartbeat timing.
struct PeerMonitorConfig {
    std::chrono::milliseconds heartbeat_period{100};  ///< how often each side sends a Heartbeat
    int missed_beats_to_dead = 3;  ///< a peer silent this many periods is dead (>= 1)

    /// Throws std::invalid_argument naming the field, value and rule.
    void Validate() const;
};

/// What the monitor knows of a peer.
enum class PeerState { kUnknown, kAlive, kDead };

/// A change of one peer's state.
struct PeerEvent {
    std::uint32_t robot_id = 0;
    PeerState state = PeerState::kUnknown;  ///< the new state (kAlive or kDead)
};

/// Tracks when each peer was last heard. Not thread-safe: one actor owns it.
class PeerMonitor {
  public:
    using Clock = std::chrono::steady_clock;

    /// Validates the config.
    explicit PeerMonitor(PeerMonitorConfig config = {});

    /// Records that a message (any message, not only a Heartbeat) came from robot_id at now.
    void Heard(std::uint32_t robot_id, Clock::time_point now);
    /// Starts watching a peer not yet heard from: it turns dead if silent for the timeout.
    void Expect(std::uint32_t robot_id, Clock::time_point now);
    /// Updates the states at now and returns the transitions since the last Tick, in robot order.
    std::vector<PeerEvent> Tick(Clock::time_point now);
    /// True when this side should send its own Heartbeat at now (then call HeartbeatSent).
    bool HeartbeatDue(Clock::time_point now) const;
    /// Records that this side sent a Heartbeat at now.
    void HeartbeatSent(Clock::time_point now);
    /// The state as of the last Tick.
    PeerState state(std::uint32_t robot_id) const;

  private:
    struct Peer {
        Clock::time_point last_heard;
        PeerState state = PeerState::kUnknown;
        bool heard_since_tick = false;
    };
    PeerMonitorConfig config_;
    std::map<std::uint32_t, Peer> peers_;
    std::optional<Clock::time_point> last_sent_;
};

}  // namespace certislam::transport
