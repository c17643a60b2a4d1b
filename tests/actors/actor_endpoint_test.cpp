// Actors over the transport's Endpoint (envelope + zero-copy binary frames): the same actor code
// over inproc and tcp loopback delivers the same messages; inproc moves the frame without a copy.
#include <gtest/gtest.h>

#include <chrono>
#include <future>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "actors/actor.h"
#include "certislam/v1/control.pb.h"
#include "transport/endpoint.h"

namespace certislam::actors {
namespace {

constexpr std::size_t kMessages = 500;
constexpr std::uint64_t kThrowAt = 123;  ///< the sink's handler throws on this sequence number
constexpr auto kDeliveryTimeout = std::chrono::seconds(20);

/// Deterministic binary frames of varied size (fixed seed), one of them 4 MB.
std::vector<transport::SharedBuffer> MakeFrames() {
    std::mt19937 rng(11);
    std::uniform_int_distribution<int> size(1, 8192);
    std::vector<transport::SharedBuffer> frames;
    for (std::size_t i = 0; i < kMessages; ++i) {
        std::vector<std::byte> bytes(i == 9 ? (std::size_t{4} << 20) : size(rng));
        for (auto& b : bytes) b = static_cast<std::byte>(rng() & 0xff);
        frames.push_back(transport::SharedBuffer::Adopt(std::move(bytes)));
    }
    return frames;
}

transport::EndpointConfig PullConfig(const std::string& address) {
    transport::EndpointConfig config;
    config.edge = "test-stream";
    config.role = transport::Role::kPull;
    config.bind = {address};
    config.max_queue_messages = 2 * kMessages;
    return config;
}

class EndpointSink final : public Actor {
  public:
    EndpointSink(zmq::context_t& context, std::string address)
        : Actor("endpoint-sink", context), address_(std::move(address)) {}
    ~EndpointSink() override { Stop(); }

    std::string bound;
    std::promise<void> done;
    std::vector<std::uint64_t> sequence;      ///< read after Stop()
    std::vector<std::string> bytes;           ///< read after Stop()
    std::vector<const std::byte*> addresses;  ///< where each frame's bytes were
    std::optional<transport::EndpointCounters> endpoint_counters;

  protected:
    void OnStart() override {
        endpoint_.emplace(Context(), PullConfig(address_));
        bound = endpoint_->bound_addresses().at(0);
        WatchEndpoint(*endpoint_, [this](transport::Message& message) { OnMessage(message); });
    }
    void OnStop() override {
        endpoint_counters = endpoint_->counters();
        endpoint_.reset();
    }

  private:
    void OnMessage(transport::Message& message) {
        const auto heartbeat = transport::Unpack<v1::Heartbeat>(message);
        const std::uint64_t seq = heartbeat ? heartbeat->header().sequence() : ~0ull;
        if (++seen_ == kMessages) done.set_value();
        if (seq == kThrowAt) throw std::runtime_error("handler failure on purpose");
        sequence.push_back(seq);
        const auto& frame = message.frames.at(0);
        bytes.emplace_back(reinterpret_cast<const char*>(frame.data()), frame.size());
        addresses.push_back(frame.data());
    }

    std::string address_;
    std::optional<transport::Endpoint> endpoint_;
    std::size_t seen_ = 0;
};

class EndpointSource final : public Actor {
  public:
    EndpointSource(zmq::context_t& context, std::string address,
                   const std::vector<transport::SharedBuffer>& frames)
        : Actor("endpoint-source", context), address_(std::move(address)), frames_(frames) {}
    ~EndpointSource() override { Stop(); }

  protected:
    void OnStart() override {
        transport::EndpointConfig config;
        config.edge = "test-stream";
        config.role = transport::Role::kPush;
        config.connect = {address_};
        config.max_queue_messages = 2 * kMessages;
        endpoint_.emplace(Context(), config);
        Post([this] { Pump(); });
    }
    void OnStop() override { endpoint_.reset(); }

  private:
    void Pump() {
        for (int k = 0; k < 50 && next_ < frames_.size(); ++k, ++next_) {
            v1::Heartbeat heartbeat;
            heartbeat.mutable_header()->set_robot_id(1);
            heartbeat.mutable_header()->set_sequence(next_);
            endpoint_->Send(transport::Pack(heartbeat, {frames_[next_]}));
        }
        if (next_ < frames_.size()) Post([this] { Pump(); });
    }

    std::string address_;
    const std::vector<transport::SharedBuffer>& frames_;
    std::optional<transport::Endpoint> endpoint_;
    std::size_t next_ = 0;
};

struct Delivery {
    std::vector<std::uint64_t> sequence;
    std::vector<std::string> bytes;
    std::vector<const std::byte*> addresses;
    ActorCounters sink;
    transport::EndpointCounters endpoint;
};

Delivery RunExchange(zmq::context_t& context, const std::string& address,
                     const std::vector<transport::SharedBuffer>& frames) {
    EndpointSink sink(context, address);
    std::future<void> done = sink.done.get_future();
    sink.Start();
    EndpointSource source(context, sink.bound, frames);
    source.Start();
    EXPECT_EQ(done.wait_for(kDeliveryTimeout), std::future_status::ready) << address;
    source.Stop();
    sink.Stop();
    return {sink.sequence, sink.bytes, sink.addresses, sink.Counters(),
            sink.endpoint_counters.value_or(transport::EndpointCounters{})};
}

TEST(ActorEndpoint, InprocAndTcpDeliverTheSameMessagesWithTheSameActorCode) {
    zmq::context_t context;
    const std::vector<transport::SharedBuffer> frames = MakeFrames();
    const Delivery inproc = RunExchange(context, "inproc://actor-endpoint", frames);
    const Delivery tcp = RunExchange(context, "tcp://127.0.0.1:*", frames);

    ASSERT_EQ(inproc.sequence.size(), kMessages - 1);
    std::size_t k = 0;
    for (std::uint64_t seq = 0; seq < kMessages; ++seq) {
        if (seq == kThrowAt) continue;
        ASSERT_EQ(inproc.sequence[k], seq);
        const auto& sent = frames[seq];
        ASSERT_EQ(inproc.bytes[k],
                  std::string(reinterpret_cast<const char*>(sent.data()), sent.size()));
        EXPECT_EQ(inproc.addresses[k], sent.data()) << "inproc frame " << seq << " was copied";
        EXPECT_NE(tcp.addresses[k], sent.data());
        ++k;
    }
    EXPECT_EQ(tcp.sequence, inproc.sequence);
    EXPECT_TRUE(tcp.bytes == inproc.bytes);
    EXPECT_EQ(inproc.sink.handled, kMessages - 1);
    EXPECT_EQ(inproc.sink.handler_errors, 1u);
    EXPECT_EQ(tcp.sink, inproc.sink);
    EXPECT_EQ(inproc.endpoint.received, kMessages);
    EXPECT_EQ(tcp.endpoint.received, kMessages);
    EXPECT_EQ(tcp.endpoint.dropped_malformed, 0u);
}

}  // namespace
}  // namespace certislam::actors
