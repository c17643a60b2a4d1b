// Peer liveness from heartbeats.
#include "transport/peer_monitor.h"

#include <stdexcept>
#include <string>

namespace certislam::transport {

void PeerMonitorConfig::Validate() const {
    if (heartbeat_period.count() <= 0) {
        throw std::invalid_argument(
            "PeerMonitorConfig.heartbeat_period = " + std::to_string(heartbeat_period.count()) +
            " ms: must be positive");
    }
    if (missed_beats_to_dead < 1) {
        throw std::invalid_argument("PeerMonitorConfig.missed_beats_to_dead = " +
                                    std::to_string(missed_beats_to_dead) + ": must be >= 1");
    }
}

PeerMonitor::PeerMonitor(PeerMonitorConfig config) : config_(config) { config_.Validate(); }

void PeerMonitor::Heard(std::uint32_t robot_id, Clock::time_point now) {
    Peer& peer = peers_[robot_id];
    peer.last_heard = now;
    peer.heard_since_tick = true;
}

void PeerMonitor::Expect(std::uint32_t robot_id, Clock::time_point now) {
    if (peers_.count(robot_id) == 0) peers_[robot_id].last_heard = now;
}

std::vector<PeerEvent> PeerMonitor::Tick(Clock::time_point now) {
    const auto timeout = config_.heartbeat_period * config_.missed_beats_to_dead;
    std::vector<PeerEvent> events;
    for (auto& [robot_id, peer] : peers_) {
        const bool silent = now - peer.last_heard > timeout;
        PeerState next = peer.state;
        if (silent) {
            next = PeerState::kDead;
        } else if (peer.heard_since_tick) {
            next = PeerState::kAlive;
        }
        peer.heard_since_tick = false;
        if (next != peer.state && next != PeerState::kUnknown) {
            events.push_back({robot_id, next});
        }
        peer.state = next;
    }
    return events;
}

bool PeerMonitor::HeartbeatDue(Clock::time_point now) const {
    return !last_sent_ || now - *last_sent_ >= config_.heartbeat_period;
}

void PeerMonitor::HeartbeatSent(Clock::time_point now) { last_sent_ = now; }

PeerState PeerMonitor::state(std::uint32_t robot_id) const {
    const auto it = peers_.find(robot_id);
    return it == peers_.end() ? PeerState::kUnknown : it->second.state;
}

}  // namespace certislam::transport
