// Endpoints over real sockets (inproc, ipc, tcp loopback): handshake, delivery, queue policies.
#include "transport/endpoint.h"

#include <gtest/gtest.h>

#include <stdexcept>

#include <thread>

#include "certislam/v1/control.pb.h"
#include "tests/transport/test_util.h"
#include "transport/context.h"

namespace certislam::transport {
namespace {

using testing::Config;
using testing::Kind;
using testing::TestMessage;

constexpr std::chrono::milliseconds kTimeout{5000};

class EndpointOverEachTransport : public ::testing::TestWithParam<Kind> {
  protected:
    zmq::context_t context_;
    testing::TempDir dir_;
    std::string address() { return testing::BindAddress(GetParam(), dir_); }
};

TEST_P(EndpointOverEachTransport, StreamStartsAfterHandshakeAndDeliversEveryMessageInOrder) {
    Endpoint publisher(context_, Config(Role::kPublisher, address(), true));
    Endpoint subscriber(context_, Config(Role::kSubscriber, publisher.bound_addresses()[0], false));
    ASSERT_TRUE(publisher.WaitForSubscribers(1, kTimeout));
    ASSERT_TRUE(subscriber.WaitReady(kTimeout));

    constexpr int kCount = 200;
    for (int i = 0; i < kCount; ++i) ASSERT_EQ(publisher.Send(TestMessage(i)), SendStatus::kSent);
    for (int i = 0; i < kCount; ++i) {
        const auto message = subscriber.Receive(kTimeout);
        ASSERT_TRUE(message.has_value()) << "message " << i;
        EXPECT_EQ(message->envelope.header().sequence(), static_cast<std::uint64_t>(i));
    }
    EXPECT_FALSE(subscriber.Receive().has_value());  // would block: empty, not an error
    const EndpointCounters counters = subscriber.counters();
    EXPECT_EQ(counters.received, static_cast<std::uint64_t>(kCount));
    EXPECT_EQ(counters.dropped_queue_full + counters.dropped_malformed, 0u);
    EXPECT_EQ(publisher.counters().sent, static_cast<std::uint64_t>(kCount) + 1);  // + Ready
}

// A message for one robot reaches only that robot's subscriber; a broadcast reaches both; the
// publisher counts each subscriber once (its robot topic is not a second hello).
TEST_P(EndpointOverEachTransport, MessageForOneRobotReachesOnlyThatRobotsSubscriber) {
    Endpoint publisher(context_, Config(Role::kPublisher, address(), true));
    auto config_of = [&](std::uint32_t robot) {
        auto c = Config(Role::kSubscriber, publisher.bound_addresses()[0], false);
        c.robot_id = robot;
        return c;
    };
    Endpoint robot2(context_, config_of(2));
    Endpoint robot12(context_, config_of(12));  // "R1" would be a prefix of "R12": not a topic
    Endpoint robot1(context_, config_of(1));
    ASSERT_TRUE(publisher.WaitForSubscribers(3, kTimeout));
    ASSERT_TRUE(robot2.WaitReady(kTimeout) && robot12.WaitReady(kTimeout) &&
                robot1.WaitReady(kTimeout));
    EXPECT_EQ(publisher.subscribers(), 3u);
    ASSERT_EQ(publisher.SendToRobot(1, TestMessage(1)), SendStatus::kSent);
    ASSERT_EQ(publisher.SendToRobot(2, TestMessage(2)), SendStatus::kSent);
    ASSERT_EQ(publisher.SendToRobot(7, TestMessage(7)), SendStatus::kSent);  // nobody's
    ASSERT_EQ(publisher.Send(TestMessage(100)), SendStatus::kSent);
    // Each stream is in order, so the broadcast arriving last proves nothing else is on its way.
    auto sequences = [](Endpoint& e) {
        std::vector<std::uint64_t> out;
        while (auto m = e.Receive(kTimeout)) {
            out.push_back(m->envelope.header().sequence());
            if (out.back() == 100) break;
        }
        return out;
    };
    EXPECT_EQ(sequences(robot1), (std::vector<std::uint64_t>{1, 100}));
    EXPECT_EQ(sequences(robot2), (std::vector<std::uint64_t>{2, 100}));
    EXPECT_EQ(sequences(robot12), (std::vector<std::uint64_t>{100}));
    for (Endpoint* e : {&robot1, &robot2, &robot12}) {
        EXPECT_FALSE(e->Receive().has_value());
        EXPECT_EQ(e->counters().dropped_malformed, 0u);
    }
    Endpoint push(context_, Config(Role::kPush, address(), true));
    EXPECT_THROW(push.SendToRobot(1, TestMessage(1)), std::logic_error);
}

TEST_P(EndpointOverEachTransport, DealerHandshakeThenRouterRepliesToTheRightPeer) {
    Endpoint router(context_, Config(Role::kRouter, address(), true));
    const std::string bound = router.bound_addresses()[0];
    std::thread server([&router] {
        // Echo each request back to its sender, until a Shutdown.
        while (auto request = router.Receive(kTimeout)) {
            if (request->Is<v1::Shutdown>()) return;
            if (request->Is<v1::Hello>()) continue;
            router.SendTo(request->peer, *request);
        }
    });
    Endpoint dealer_a(context_, Config(Role::kDealer, bound, false));
    Endpoint dealer_b(context_, Config(Role::kDealer, bound, false));
    ASSERT_TRUE(dealer_a.WaitReady(kTimeout));
    ASSERT_TRUE(dealer_b.WaitReady(kTimeout));
    ASSERT_EQ(dealer_a.Send(TestMessage(10)), SendStatus::kSent);
    ASSERT_EQ(dealer_b.Send(TestMessage(20)), SendStatus::kSent);
    const auto reply_a = dealer_a.Receive(kTimeout);
    const auto reply_b = dealer_b.Receive(kTimeout);
    ASSERT_TRUE(reply_a && reply_b);
    EXPECT_EQ(reply_a->envelope.header().sequence(), 10u);
    EXPECT_EQ(reply_b->envelope.header().sequence(), 20u);
    v1::Shutdown shutdown;
    ASSERT_EQ(dealer_a.Send(Pack(shutdown)), SendStatus::kSent);
    server.join();
    EXPECT_EQ(router.counters().control_received, 2u);  // two hellos answered
}

INSTANTIATE_TEST_SUITE_P(Transports, EndpointOverEachTransport,
                         ::testing::Values(Kind::kInproc, Kind::kIpc, Kind::kTcp),
                         [](const auto& info) { return testing::Name(info.param); });

class EndpointPolicy : public ::testing::Test {
  protected:
    zmq::context_t context_;
    testing::TempDir dir_;
};

TEST_F(EndpointPolicy, LatestStreamKeepsTheNewestAndCountsDroppedOldest) {
    const std::string address = testing::BindAddress(Kind::kInproc, dir_);
    Endpoint publisher(context_, Config(Role::kPublisher, address, true, Delivery::kLatest));
    auto sub_config = Config(Role::kSubscriber, address, false, Delivery::kLatest);
    sub_config.max_queue_messages = 4;
    Endpoint subscriber(context_, sub_config);
    ASSERT_TRUE(publisher.WaitForSubscribers(1, kTimeout));
    ASSERT_TRUE(subscriber.WaitReady(kTimeout));

    // Inproc pipe capacity is the sum of both HWMs (1000 + 4): all ten reach the socket.
    for (int i = 0; i < 10; ++i) ASSERT_EQ(publisher.Send(TestMessage(i)), SendStatus::kSent);
    for (int expected = 6; expected < 10; ++expected) {
        const auto message = subscriber.Receive();
        ASSERT_TRUE(message.has_value());
        EXPECT_EQ(message->envelope.header().sequence(), static_cast<std::uint64_t>(expected));
    }
    EXPECT_FALSE(subscriber.Receive().has_value());
    EXPECT_EQ(subscriber.counters().dropped_queue_full, 6u);
    EXPECT_EQ(subscriber.counters().received, 10u);
}

TEST_F(EndpointPolicy, LatestStreamBoundsQueueBytes) {
    const std::string address = testing::BindAddress(Kind::kInproc, dir_);
    Endpoint publisher(context_, Config(Role::kPublisher, address, true, Delivery::kLatest));
    auto sub_config = Config(Role::kSubscriber, address, false, Delivery::kLatest);
    const std::vector<std::byte> kilobyte(1024);
    const std::size_t one =
        TestMessage(0, 1, {SharedBuffer::Copy(kilobyte.data(), 1024)}).ByteSize();
    sub_config.max_queue_bytes = 3 * one + one / 2;  // room for three
    Endpoint subscriber(context_, sub_config);
    ASSERT_TRUE(publisher.WaitForSubscribers(1, kTimeout));
    ASSERT_TRUE(subscriber.WaitReady(kTimeout));
    for (int i = 0; i < 8; ++i) {
        publisher.Send(TestMessage(i, 1, {SharedBuffer::Copy(kilobyte.data(), 1024)}));
    }
    int got = 0;
    while (auto message = subscriber.Receive()) {
        EXPECT_EQ(message->envelope.header().sequence(), static_cast<std::uint64_t>(5 + got));
        ++got;
    }
    EXPECT_EQ(got, 3);
    EXPECT_EQ(subscriber.counters().dropped_queue_full, 5u);
}

TEST_F(EndpointPolicy, LatestSenderDropsWhenFullAndCountsEveryDrop) {
    const std::string address = testing::BindAddress(Kind::kInproc, dir_);
    auto pub_config = Config(Role::kPublisher, address, true, Delivery::kLatest);
    pub_config.max_queue_messages = 2;
    Endpoint publisher(context_, pub_config);
    auto sub_config = Config(Role::kSubscriber, address, false, Delivery::kLatest);
    sub_config.max_queue_messages = 2;
    Endpoint subscriber(context_, sub_config);
    ASSERT_TRUE(publisher.WaitForSubscribers(1, kTimeout));
    ASSERT_TRUE(subscriber.WaitReady(kTimeout));

    int sent = 0;
    int dropped = 0;
    for (int i = 0; i < 20; ++i) {
        const SendStatus status = publisher.Send(TestMessage(i));
        if (status == SendStatus::kSent) ++sent;
        if (status == SendStatus::kDropped) ++dropped;
    }
    EXPECT_EQ(sent + dropped, 20);
    EXPECT_GT(dropped, 0);
    EXPECT_EQ(publisher.counters().dropped_queue_full, static_cast<std::uint64_t>(dropped));
    // What the publisher says it sent reached the subscriber's socket.
    EXPECT_EQ(subscriber.counters().received + subscriber.counters().dropped_queue_full, 0u);
    while (subscriber.Receive()) {
    }
    EXPECT_EQ(subscriber.counters().received, static_cast<std::uint64_t>(sent));
}

class ReliableEdge : public ::testing::TestWithParam<Kind> {
  protected:
    zmq::context_t context_;
    testing::TempDir dir_;
};

TEST_P(ReliableEdge, AppliesBackpressureToASenderWhoseReaderStallsAndLosesNothing) {
    auto pull_config = Config(Role::kPull, testing::BindAddress(GetParam(), dir_), true);
    pull_config.max_queue_messages = 4;
    Endpoint pull(context_, pull_config);
    auto push_config = Config(Role::kPush, pull.bound_addresses()[0], false);
    push_config.max_queue_messages = 4;
    push_config.send_timeout_ms = 20;
    Endpoint push(context_, push_config);

    // 64 KB frames so that tcp's kernel buffers fill too; each frame is shared, not copied.
    const std::vector<std::byte> block(64 << 10);
    const SharedBuffer payload = SharedBuffer::Copy(block.data(), block.size());
    std::vector<std::uint64_t> accepted;
    int backpressure = 0;
    for (std::uint64_t i = 0; i < 20000 && backpressure == 0; ++i) {
        const SendStatus status = push.Send(TestMessage(i, 1, {payload}));
        if (status == SendStatus::kSent) accepted.push_back(i);
        if (status == SendStatus::kBackpressure) ++backpressure;
    }
    ASSERT_EQ(backpressure, 1) << "a reader that never reads must stop a reliable sender";
    EXPECT_EQ(push.counters().send_backpressure, 1u);
    for (const std::uint64_t expected : accepted) {
        const auto message = pull.Receive(kTimeout);
        ASSERT_TRUE(message.has_value()) << "lost message " << expected;
        EXPECT_EQ(message->envelope.header().sequence(), expected);
    }
    EXPECT_EQ(pull.counters().dropped_queue_full, 0u);
    EXPECT_EQ(pull.counters().received, accepted.size());
}

INSTANTIATE_TEST_SUITE_P(Transports, ReliableEdge, ::testing::Values(Kind::kInproc, Kind::kTcp),
                         [](const auto& info) { return testing::Name(info.param); });

// Linger 0: messages queued for a peer that never answers do not hold the context open.
TEST(EndpointLinger, EverySocketHasLingerZeroAndAContextClosesWithUndeliveredMessages) {
    constexpr auto kPromptClose = std::chrono::seconds(2);
    zmq::context_t context;
    testing::TempDir dir;
    for (Role role : {Role::kPublisher, Role::kSubscriber, Role::kDealer, Role::kRouter,
                      Role::kPush, Role::kPull}) {
        Endpoint endpoint(context, Config(role, testing::BindAddress(Kind::kIpc, dir), true));
        EXPECT_EQ(endpoint.socket().get(zmq::sockopt::linger), 0);
    }
    {
        // Nobody listens on this port: connect() makes a pipe and the message waits in it.
        zmq::context_t probe_context;
        zmq::socket_t probe(probe_context, zmq::socket_type::pull);
        probe.bind("tcp://127.0.0.1:*");
        const std::string silent = probe.get(zmq::sockopt::last_endpoint);
        probe.close();
        Endpoint push(context, Config(Role::kPush, silent, false, Delivery::kLatest));
        ASSERT_EQ(push.Send(TestMessage(1)), SendStatus::kSent);
    }
    const auto start = std::chrono::steady_clock::now();
    context.close();  // with the default linger (-1) this would wait for the peer forever
    EXPECT_LT(std::chrono::steady_clock::now() - start, kPromptClose);
}

TEST(EndpointConfig, ValidateNamesTheFieldAndTheRule) {
    EndpointConfig config = Config(Role::kPull, "udp://127.0.0.1:5", true);
    try {
        config.Validate();
        FAIL() << "udp:// accepted";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("bind"), std::string::npos);
        EXPECT_NE(std::string(e.what()).find("udp://"), std::string::npos);
    }
    config = Config(Role::kPull, "ipc:///tmp/x", true);
    config.max_queue_bytes = 0;
    EXPECT_THROW(config.Validate(), std::invalid_argument);
    EdgeTable table;
    table.Add("keyframes/pub", Config(Role::kPublisher, "inproc://keyframes", true));
    EXPECT_EQ(table.Get("keyframes/pub").bind[0], "inproc://keyframes");
    EXPECT_THROW(table.Get("descriptors/sub"), std::invalid_argument);
}

}  // namespace
}  // namespace certislam::transport

namespace certislam::transport {
namespace {

// libzmq allows 1023 sockets per context by default; an in-process team of 20 robots opens more.
TEST(ReserveSockets, AContextOpensMoreSocketsThanLibzmqsDefault) {
    constexpr int kSockets = 1500;
    const auto open_all = [](zmq::context_t& context) {
        std::vector<zmq::socket_t> sockets;
        sockets.reserve(kSockets);
        for (int i = 0; i < kSockets; ++i) sockets.emplace_back(context, zmq::socket_type::pair);
        return sockets.size();
    };
    zmq::context_t plain;
    EXPECT_THROW(open_all(plain), zmq::error_t);
    zmq::context_t reserved;
    ReserveSockets(reserved, kSockets);
    EXPECT_EQ(open_all(reserved), static_cast<size_t>(kSockets));
}

}  // namespace
}  // namespace certislam::transport
