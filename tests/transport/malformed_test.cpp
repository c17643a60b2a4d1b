// Malformed bytes sent over real sockets (truncated, garbage, wrong version, wrong frame count)
// are dropped and counted by the receiving endpoint, which keeps delivering valid messages.
#include <gtest/gtest.h>

#include <random>
#include <zmq_addon.hpp>

#include "tests/transport/test_util.h"
#include "transport/endpoint.h"

namespace certislam::transport {
namespace {

using testing::Config;
using testing::Kind;
using testing::TestMessage;

constexpr std::chrono::milliseconds kTimeout{5000};

// Sends `frames`, behind a topic frame when `topic` is set (what a publisher's readers expect).
void SendRaw(zmq::socket_t& socket, std::vector<zmq::message_t>&& frames,
             const char* topic = nullptr) {
    if (topic != nullptr) frames.insert(frames.begin(), zmq::message_t(std::string(topic)));
    ASSERT_TRUE(zmq::send_multipart(socket, frames).has_value());
}

std::vector<zmq::message_t> Frames(std::initializer_list<std::string> parts) {
    std::vector<zmq::message_t> frames;
    for (const auto& part : parts) frames.emplace_back(part.data(), part.size());
    return frames;
}

// Sends one batch of bad messages and a valid one last; returns how many of each kind it sent.
struct BadBatch {
    int malformed = 0;
    int version = 0;
};

BadBatch SendBadBatch(zmq::socket_t& raw, std::uint64_t valid_sequence,
                      const char* topic = nullptr) {
    BadBatch batch;
    const std::vector<std::byte> cloud(4096);
    const Message good = TestMessage(7, 1, {SharedBuffer::Copy(cloud.data(), cloud.size())});
    const std::string envelope = Encode(good)[0].to_string();

    SendRaw(raw, Frames({envelope.substr(0, envelope.size() / 2), std::string(4096, 'c')}), topic);
    ++batch.malformed;  // truncated envelope
    SendRaw(raw, Frames({envelope}), topic);
    ++batch.malformed;  // frame missing
    SendRaw(raw, Frames({envelope, std::string(4096, 'c'), std::string(4096, 'c')}), topic);
    ++batch.malformed;  // frame extra
    SendRaw(raw, Frames({envelope, std::string(100, 'c')}), topic);
    ++batch.malformed;  // frame shorter than declared
    std::mt19937 rng(11);
    for (int i = 0; i < 20; ++i) {
        std::string garbage(1 + i * 13, '\0');
        for (auto& c : garbage) c = static_cast<char>(rng());
        SendRaw(raw, Frames({garbage}), topic);
        ++batch.malformed;
    }
    Message future = TestMessage(8);
    future.envelope.set_schema_major(kSchemaMajor + 1);
    SendRaw(raw, Encode(future), topic);
    ++batch.version;
    SendRaw(raw, Encode(TestMessage(valid_sequence)), topic);
    return batch;
}

class MalformedOverEachTransport : public ::testing::TestWithParam<Kind> {};

TEST_P(MalformedOverEachTransport, PullDropsAndCountsEveryBadMessageAndKeepsTheGoodOne) {
    zmq::context_t context;
    testing::TempDir dir;
    Endpoint pull(context, Config(Role::kPull, testing::BindAddress(GetParam(), dir), true));
    zmq::socket_t raw(context, zmq::socket_type::push);
    raw.set(zmq::sockopt::linger, 0);
    raw.connect(pull.bound_addresses()[0]);

    const BadBatch batch = SendBadBatch(raw, 99);
    const auto message = pull.Receive(kTimeout);
    ASSERT_TRUE(message.has_value());
    EXPECT_EQ(message->envelope.header().sequence(), 99u);
    const EndpointCounters counters = pull.counters();
    EXPECT_EQ(counters.dropped_malformed, static_cast<std::uint64_t>(batch.malformed));
    EXPECT_EQ(counters.dropped_version, static_cast<std::uint64_t>(batch.version));
    EXPECT_EQ(counters.received, 1u);
}

INSTANTIATE_TEST_SUITE_P(Transports, MalformedOverEachTransport,
                         ::testing::Values(Kind::kInproc, Kind::kIpc, Kind::kTcp),
                         [](const auto& info) { return testing::Name(info.param); });

TEST(Malformed, RouterDropsBadMessagesFromADealer) {
    zmq::context_t context;
    Endpoint router(context, Config(Role::kRouter, "tcp://127.0.0.1:*", true));
    zmq::socket_t raw(context, zmq::socket_type::dealer);
    raw.set(zmq::sockopt::linger, 0);
    raw.connect(router.bound_addresses()[0]);
    const BadBatch batch = SendBadBatch(raw, 5);
    const auto message = router.Receive(kTimeout);
    ASSERT_TRUE(message.has_value());
    EXPECT_EQ(message->envelope.header().sequence(), 5u);
    EXPECT_FALSE(message->peer.empty());
    EXPECT_EQ(router.counters().dropped_malformed, static_cast<std::uint64_t>(batch.malformed));
    EXPECT_EQ(router.counters().dropped_version, 1u);
}

// A raw publisher's messages travel behind a topic frame, as an Endpoint's do: the bad batch
// behind the broadcast topic, and topic frames that only start like a subscribed topic (ZeroMQ
// matches prefixes) or come alone are dropped and counted too.
TEST(Malformed, SubscriberDropsBadMessagesFromARawPublisher) {
    zmq::context_t context;
    zmq::socket_t raw(context, zmq::socket_type::xpub);
    raw.set(zmq::sockopt::linger, 0);
    raw.bind("tcp://127.0.0.1:*");
    auto config = Config(Role::kSubscriber, raw.get(zmq::sockopt::last_endpoint), false);
    config.robot_id = 3;
    Endpoint subscriber(context, config);
    zmq::message_t subscription;  // handshake without sleeps: wait for both subscriptions
    ASSERT_TRUE(raw.recv(subscription).has_value());
    ASSERT_TRUE(raw.recv(subscription).has_value());
    const std::string envelope = Encode(TestMessage(5))[0].to_string();
    SendRaw(raw, Frames({"Bx", envelope}));    // starts like the broadcast topic
    SendRaw(raw, Frames({"R3.1", envelope}));  // starts like robot 3's
    SendRaw(raw, Frames({"B"}));               // a topic and nothing else
    constexpr int kTopicDrops = 3;
    const BadBatch batch = SendBadBatch(raw, 6, kBroadcastTopic);
    const auto message = subscriber.Receive(kTimeout);
    ASSERT_TRUE(message.has_value());
    EXPECT_EQ(message->envelope.header().sequence(), 6u);
    EXPECT_EQ(subscriber.counters().dropped_malformed,
              static_cast<std::uint64_t>(batch.malformed + kTopicDrops));
    EXPECT_EQ(subscriber.counters().dropped_version, static_cast<std::uint64_t>(batch.version));
}

// A publisher counts a subscriber once its robot topic's subscription arrives (after its
// broadcast one), and a subscription to everything, the framing before topics, as another
// version: such a subscriber would read every message as malformed.
TEST(Malformed, PublisherCountsAHelloOnlyAtARobotTopicAndAnOldSubscriberAsAnotherVersion) {
    zmq::context_t context;
    Endpoint publisher(context, Config(Role::kPublisher, "tcp://127.0.0.1:*", true));
    zmq::socket_t raw(context, zmq::socket_type::sub);
    raw.set(zmq::sockopt::linger, 0);
    raw.connect(publisher.bound_addresses().front());
    constexpr std::chrono::milliseconds kShort{300};
    raw.set(zmq::sockopt::subscribe, "");
    raw.set(zmq::sockopt::subscribe, kBroadcastTopic);
    raw.set(zmq::sockopt::subscribe, "Rx.");  // not a robot topic
    EXPECT_FALSE(publisher.WaitForSubscribers(1, kShort));
    EXPECT_EQ(publisher.counters().dropped_version, 1u);
    raw.set(zmq::sockopt::subscribe, RobotTopic(4));
    EXPECT_TRUE(publisher.WaitForSubscribers(1, kTimeout));
    EXPECT_FALSE(publisher.WaitForSubscribers(2, kShort));
    EXPECT_EQ(publisher.subscribers(), 1u);
    EXPECT_EQ(publisher.counters().dropped_version, 1u);
}

}  // namespace
}  // namespace certislam::transport
