// Heartbeats: the monitor's transitions on a fixed timeline, then a real peer over tcp loopback
// that beats, dies (its socket closes) and comes back, marked alive, dead and alive again.
#include "transport/peer_monitor.h"

#include <gtest/gtest.h>

#include <atomic>
#include <thread>

#include "certislam/v1/control.pb.h"
#include "tests/transport/test_util.h"
#include "transport/endpoint.h"

namespace certislam::transport {
namespace {

using Clock = PeerMonitor::Clock;
using std::chrono::milliseconds;

constexpr milliseconds kPeriod{20};
constexpr int kMissed = 3;
constexpr milliseconds kWait{5000};  // longest a socket test waits for a transition

PeerMonitorConfig TestConfig() {
    PeerMonitorConfig config;
    config.heartbeat_period = kPeriod;
    config.missed_beats_to_dead = kMissed;
    return config;
}

TEST(PeerMonitor, AliveWhenHeardDeadAfterMissedBeatsAliveAgainWhenHeard) {
    PeerMonitor monitor(TestConfig());
    const Clock::time_point t0{};
    EXPECT_EQ(monitor.state(7), PeerState::kUnknown);
    monitor.Heard(7, t0);
    auto events = monitor.Tick(t0 + milliseconds(1));
    ASSERT_EQ(events.size(), 1u);
    EXPECT_EQ(events[0].robot_id, 7u);
    EXPECT_EQ(events[0].state, PeerState::kAlive);
    // Silent for exactly the timeout: still alive; one more millisecond: dead, reported once.
    EXPECT_TRUE(monitor.Tick(t0 + kPeriod * kMissed).empty());
    EXPECT_EQ(monitor.state(7), PeerState::kAlive);
    events = monitor.Tick(t0 + kPeriod * kMissed + milliseconds(1));
    ASSERT_EQ(events.size(), 1u);
    EXPECT_EQ(events[0].state, PeerState::kDead);
    EXPECT_TRUE(monitor.Tick(t0 + milliseconds(500)).empty());
    monitor.Heard(7, t0 + milliseconds(600));
    events = monitor.Tick(t0 + milliseconds(601));
    ASSERT_EQ(events.size(), 1u);
    EXPECT_EQ(events[0].state, PeerState::kAlive);
}

TEST(PeerMonitor, AnExpectedPeerNeverHeardTurnsDeadAndBeatsFollowThePeriod) {
    PeerMonitor monitor(TestConfig());
    const Clock::time_point t0{};
    monitor.Expect(3, t0);
    EXPECT_TRUE(monitor.Tick(t0 + kPeriod).empty());
    const auto events = monitor.Tick(t0 + kPeriod * (kMissed + 1));
    ASSERT_EQ(events.size(), 1u);
    EXPECT_EQ(events[0].state, PeerState::kDead);

    EXPECT_TRUE(monitor.HeartbeatDue(t0));
    monitor.HeartbeatSent(t0);
    EXPECT_FALSE(monitor.HeartbeatDue(t0 + kPeriod - milliseconds(1)));
    EXPECT_TRUE(monitor.HeartbeatDue(t0 + kPeriod));

    PeerMonitorConfig bad;
    bad.missed_beats_to_dead = 0;
    EXPECT_THROW(PeerMonitor{bad}, std::invalid_argument);
}

// A robot that sends a Heartbeat every period over a publisher connecting to `address`, until
// destroyed (its socket closes with linger 0: the peer is gone).
class BeatingPeer {
  public:
    BeatingPeer(zmq::context_t& context, const std::string& address, std::uint32_t robot_id)
        : thread_([this, &context, address, robot_id] { Run(context, address, robot_id); }) {}
    ~BeatingPeer() {
        stop_ = true;
        thread_.join();
    }

  private:
    void Run(zmq::context_t& context, const std::string& address, std::uint32_t robot_id) {
        auto config = testing::Config(Role::kPublisher, address, false, Delivery::kLatest);
        Endpoint out(context, config);
        PeerMonitor own(TestConfig());  // only for its sending cadence
        std::uint64_t sequence = 0;
        while (!stop_) {
            const auto now = Clock::now();
            if (own.HeartbeatDue(now)) {
                v1::Heartbeat beat;
                beat.mutable_header()->set_robot_id(robot_id);
                beat.mutable_header()->set_sequence(sequence++);
                beat.set_period_ms(static_cast<std::uint32_t>(kPeriod.count()));
                out.Send(Pack(beat));
                own.HeartbeatSent(now);
            }
            std::this_thread::sleep_for(milliseconds(2));  // the beat cadence, not a sync
        }
    }

    std::atomic<bool> stop_{false};
    std::thread thread_;
};

// Receives heartbeats and ticks the monitor until robot_id reaches `wanted` or kWait passes.
bool WaitForState(Endpoint& in, PeerMonitor& monitor, std::uint32_t robot_id, PeerState wanted) {
    const auto deadline = Clock::now() + kWait;
    while (Clock::now() < deadline) {
        if (auto message = in.Receive(milliseconds(5))) {
            if (message->Is<v1::Heartbeat>()) {
                monitor.Heard(message->envelope.header().robot_id(), Clock::now());
            }
        }
        for (const auto& event : monitor.Tick(Clock::now())) {
            if (event.robot_id == robot_id && event.state == wanted) return true;
        }
    }
    return false;
}

TEST(PeerMonitor, RealPeerOverTcpIsMarkedAliveDeadWhenItsSocketClosesAndAliveAgain) {
    zmq::context_t context;
    Endpoint in(context,
                testing::Config(Role::kSubscriber, "tcp://127.0.0.1:*", true, Delivery::kLatest));
    const std::string address = in.bound_addresses().front();
    PeerMonitor monitor(TestConfig());
    constexpr std::uint32_t kRobot = 4;
    monitor.Expect(kRobot, Clock::now());
    {
        BeatingPeer peer(context, address, kRobot);
        ASSERT_TRUE(WaitForState(in, monitor, kRobot, PeerState::kAlive));
    }  // the peer's process of sending stops and its socket closes
    ASSERT_TRUE(WaitForState(in, monitor, kRobot, PeerState::kDead));
    BeatingPeer back(context, address, kRobot);  // reconnects to the same address
    EXPECT_TRUE(WaitForState(in, monitor, kRobot, PeerState::kAlive));
    EXPECT_EQ(monitor.state(kRobot), PeerState::kAlive);
}

}  // namespace
}  // namespace certislam::transport
