// Tests of the actor runtime with real actors, real sockets (inproc and tcp loopback), real timers.
#include "actors/actor.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstring>
#include <functional>
#include <future>
#include <memory>
#include <mutex>
#include <optional>
#include <random>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace certislam::actors {
namespace {

using std::chrono::milliseconds;
using std::chrono::steady_clock;

constexpr size_t kMessages = 3000;       ///< well-formed messages per exchange
constexpr size_t kMalformedEvery = 500;  ///< every 500th message is sent with one frame only
constexpr size_t kThrowAt = 1234;        ///< the sink's handler throws on this message
constexpr auto kDeliveryTimeout = std::chrono::seconds(20);
constexpr auto kPromptStop = milliseconds(250);  ///< Stop() with messages in flight
constexpr auto kTimerPeriod = milliseconds(20);
constexpr int kTicks = 10;
/// Coarse on purpose (no timing asserts beyond gross errors): catches a tick held back by far more
/// than scheduling noise, e.g. a timer re-armed only after a slow handler; under ctest -j2 on 2
/// cores a tick can be a hundred milliseconds late.
constexpr auto kMaxTimerLateness = milliseconds(500);

constexpr auto kContextCloseTimeout = std::chrono::seconds(5);

/// zmq_ctx_term blocks while any socket of the context is open: returning shows none leaked.
bool ContextClosesWithin(zmq::context_t& context, std::chrono::seconds timeout) {
    auto closed = std::make_shared<std::promise<void>>();
    std::future<void> done = closed->get_future();
    std::thread([&context, closed] {
        context.close();
        closed->set_value();
    }).detach();  // a leaked socket would block it forever: the test fails instead of hanging
    return done.wait_for(timeout) == std::future_status::ready;
}

/// Deterministic payloads of varied size (fixed seed), one of them 1 MB.
std::vector<std::string> MakePayloads() {
    std::mt19937 rng(42);
    std::uniform_int_distribution<int> size(0, 4096);
    std::uniform_int_distribution<int> byte(0, 255);
    std::vector<std::string> payloads(kMessages);
    for (size_t i = 0; i < kMessages; ++i) {
        payloads[i].resize(i == 7 ? (1u << 20) : static_cast<size_t>(size(rng)));
        for (char& c : payloads[i]) c = static_cast<char>(byte(rng));
    }
    return payloads;
}

/// Binds a PULL socket, records (sequence, payload) of two-frame messages; one-frame messages
/// are malformed; throws on message kThrowAt.
class SinkActor final : public Actor {
  public:
    SinkActor(zmq::context_t& context, std::string endpoint, size_t expected_events,
              std::chrono::microseconds work_per_message = {})
        : Actor("sink", context),
          endpoint_(std::move(endpoint)),
          expected_events_(expected_events),
          work_(work_per_message) {}
    ~SinkActor() override { Stop(); }

    std::string bound;                  ///< the endpoint actually bound (tcp port resolved)
    std::promise<void> all_seen;        ///< set when expected_events messages were seen
    std::vector<std::string> payloads;  ///< read after Stop()
    std::vector<uint64_t> sequence;     ///< read after Stop()

  protected:
    void OnStart() override {
        zmq::socket_t& socket = MakeSocket(zmq::socket_type::pull);
        socket.set(zmq::sockopt::rcvhwm, 0);
        socket.bind(endpoint_);
        bound = socket.get(zmq::sockopt::last_endpoint);
        Watch(socket, [this](Frames& frames) { return OnMessage(frames); });
    }

  private:
    Disposition OnMessage(Frames& frames) {
        const struct Seen {
            SinkActor* self;
            ~Seen() {
                if (++self->seen_ == self->expected_events_) self->all_seen.set_value();
            }
        } seen{this};
        if (work_.count() > 0) {
            const auto until = steady_clock::now() + work_;
            while (steady_clock::now() < until) {
            }
        }
        if (frames.size() != 2 || frames[0].size() != sizeof(uint64_t)) {
            return Disposition::kMalformed;
        }
        uint64_t seq = 0;
        std::memcpy(&seq, frames[0].data(), sizeof(seq));
        if (seq == kThrowAt) throw std::runtime_error("handler failure on purpose");
        sequence.push_back(seq);
        payloads.push_back(frames[1].to_string());
        return Disposition::kHandled;
    }

    std::string endpoint_;
    size_t expected_events_;
    std::chrono::microseconds work_;
    size_t seen_ = 0;
};

/// Connects a PUSH socket and sends the payloads (every kMalformedEvery-th also as a one-frame
/// message), 100 per posted task; with `forever` it starts over endlessly.
class SourceActor final : public Actor {
  public:
    SourceActor(zmq::context_t& context, std::string endpoint,
                const std::vector<std::string>& payloads, bool forever = false)
        : Actor("source", context),
          endpoint_(std::move(endpoint)),
          payloads_(payloads),
          forever_(forever) {}
    ~SourceActor() override { Stop(); }

  protected:
    void OnStart() override {
        socket_ = &MakeSocket(zmq::socket_type::push);
        socket_->set(zmq::sockopt::sndhwm, 0);
        socket_->connect(endpoint_);
        Post([this] { Pump(); });
    }

  private:
    void Pump() {
        for (int k = 0; k < 100 && next_ < payloads_.size(); ++k, ++next_) {
            const uint64_t seq = next_;
            Frames frames;
            frames.emplace_back(&seq, sizeof(seq));
            frames.emplace_back(payloads_[next_].data(), payloads_[next_].size());
            SendOrDrop(*socket_, frames);
            if (next_ % kMalformedEvery == 0) {
                Frames bad;
                bad.emplace_back("garbage", 7);
                SendOrDrop(*socket_, bad);
            }
        }
        if (forever_ && next_ == payloads_.size()) next_ = 0;
        if (next_ < payloads_.size()) Post([this] { Pump(); });
    }

    std::string endpoint_;
    const std::vector<std::string>& payloads_;
    bool forever_;
    zmq::socket_t* socket_ = nullptr;
    size_t next_ = 0;
};

struct Delivery {
    std::vector<std::string> payloads;
    std::vector<uint64_t> sequence;
    ActorCounters sink;
    ActorCounters source;
};

/// The same two actors, only the endpoint string differs.
Delivery RunExchange(zmq::context_t& context, const std::string& endpoint,
                     const std::vector<std::string>& payloads) {
    const size_t malformed = (kMessages + kMalformedEvery - 1) / kMalformedEvery;
    SinkActor sink(context, endpoint, kMessages + malformed);
    std::future<void> done = sink.all_seen.get_future();
    sink.Start();
    SourceActor source(context, sink.bound, payloads);
    source.Start();
    EXPECT_EQ(done.wait_for(kDeliveryTimeout), std::future_status::ready) << endpoint;
    source.Stop();
    sink.Stop();
    return {sink.payloads, sink.sequence, sink.Counters(), source.Counters()};
}

TEST(Actor, InprocAndTcpDeliverIdenticallyWithTheSameCode) {
    zmq::context_t context;
    const std::vector<std::string> payloads = MakePayloads();
    const Delivery inproc = RunExchange(context, "inproc://actor-test", payloads);
    const Delivery tcp = RunExchange(context, "tcp://127.0.0.1:*", payloads);

    std::vector<std::string> expected = payloads;
    expected.erase(expected.begin() + kThrowAt);
    ASSERT_EQ(inproc.payloads.size(), kMessages - 1);
    EXPECT_TRUE(inproc.payloads == expected);  // same bytes, same order
    EXPECT_TRUE(std::is_sorted(inproc.sequence.begin(), inproc.sequence.end()));
    EXPECT_TRUE(tcp.payloads == inproc.payloads);
    EXPECT_EQ(tcp.sequence, inproc.sequence);

    EXPECT_EQ(inproc.sink.handled, kMessages - 1);
    EXPECT_EQ(inproc.sink.dropped_malformed, kMessages / kMalformedEvery);
    EXPECT_EQ(inproc.sink.handler_errors, 1u);  // the actor kept running after it
    EXPECT_EQ(inproc.source.queue_full_drops, 0u);
    EXPECT_EQ(tcp.sink, inproc.sink);
    EXPECT_EQ(tcp.source, inproc.source);
    EXPECT_TRUE(ContextClosesWithin(context, kContextCloseTimeout));
}

TEST(Actor, StopWithMessagesInFlightReturnsPromptly) {
    zmq::context_t context;
    const std::vector<std::string> payloads = MakePayloads();
    SinkActor sink(context, "inproc://actor-busy", kMessages * 1000,
                   std::chrono::microseconds(200));
    sink.Start();
    SourceActor source(context, "inproc://actor-busy", payloads, /*forever=*/true);
    source.Start();
    while (sink.Counters().handled < 200) std::this_thread::yield();

    const auto t0 = steady_clock::now();
    sink.Stop();  // thousands of messages are queued behind it
    const auto sink_stop = steady_clock::now() - t0;
    source.Stop();
    const auto both_stop = steady_clock::now() - t0;
    EXPECT_LT(sink_stop, kPromptStop);
    EXPECT_LT(both_stop, kPromptStop);
    EXPECT_FALSE(sink.Running());
    EXPECT_FALSE(source.Running());
    EXPECT_TRUE(ContextClosesWithin(context, kContextCloseTimeout));
}

/// Records the time of each tick of a periodic timer and of one one-shot.
class TickActor final : public Actor {
  public:
    explicit TickActor(zmq::context_t& context) : Actor("ticker", context) {}
    ~TickActor() override { Stop(); }

    steady_clock::time_point start;
    std::vector<steady_clock::time_point> ticks;  ///< read after Stop()
    std::optional<steady_clock::time_point> once;
    std::promise<void> enough;

  protected:
    void OnStart() override {
        start = steady_clock::now();
        Every(kTimerPeriod, [this] {
            ticks.push_back(steady_clock::now());
            if (ticks.size() == kTicks) enough.set_value();
            if (ticks.size() == 3) throw std::runtime_error("tick failure on purpose");
        });
        After(kTimerPeriod * 3 / 2, [this] { once = steady_clock::now(); });
    }
};

TEST(Actor, TimerFiresAtTheExpectedCadence) {
    zmq::context_t context;
    TickActor actor(context);
    std::future<void> enough = actor.enough.get_future();
    actor.Start();
    ASSERT_EQ(enough.wait_for(kTimerPeriod * kTicks * 10), std::future_status::ready);
    actor.Stop();

    ASSERT_GE(actor.ticks.size(), static_cast<size_t>(kTicks));
    for (size_t k = 0; k < actor.ticks.size(); ++k) {
        const auto due = actor.start + kTimerPeriod * static_cast<int>(k + 1);
        EXPECT_GE(actor.ticks[k], due) << "tick " << k << " early";
        EXPECT_LT(actor.ticks[k] - due, kMaxTimerLateness) << "tick " << k << " late";
    }
    ASSERT_TRUE(actor.once.has_value());
    EXPECT_GE(*actor.once, actor.start + kTimerPeriod * 3 / 2);
    const ActorCounters counters = actor.Counters();
    EXPECT_EQ(counters.handler_errors, 1u);  // the throwing tick did not stop the timer
    EXPECT_EQ(counters.timer_fires, actor.ticks.size() + 1);
}

/// A tick busy for its first kBusyTicks, then idle; a message on its pair socket wakes it.
class IdleTickActor final : public Actor {
  public:
    explicit IdleTickActor(zmq::context_t& context) : Actor("idle", context) {}
    ~IdleTickActor() override { Stop(); }
    static constexpr int kBusyTicks = 3;
    static constexpr auto kIdlePeriod = std::chrono::seconds(3);
    std::atomic<int> ticks{0};
    std::atomic<int> messages{0};

  protected:
    void OnStart() override {
        socket_.emplace(Context(), zmq::socket_type::pair);
        socket_->set(zmq::sockopt::linger, 0);
        socket_->bind("inproc://idle");
        WatchReadable(socket_->handle(), [this] {
            zmq::message_t msg;
            while (socket_->recv(msg, zmq::recv_flags::dontwait)) ++messages;
        });
        EveryUntilIdle(kTimerPeriod, kIdlePeriod, [this] { return ++ticks < kBusyTicks; });
    }
    void OnStop() override { socket_.reset(); }

  private:
    std::optional<zmq::socket_t> socket_;
};

bool WaitUntil(const std::function<bool()>& done, std::chrono::milliseconds timeout) {
    const auto until = steady_clock::now() + timeout;
    while (!done()) {
        if (steady_clock::now() > until) return false;
        std::this_thread::sleep_for(milliseconds(2));
    }
    return true;
}

// EveryUntilIdle: busy ticks at the period, then none for far longer than many periods (the idle
// period is seconds), until a message comes: the next tick follows within the busy period (plus
// scheduling noise), not at the end of the idle one. The messages are read as they come.
TEST(Actor, AnIdleTimerSleepsUntilAMessageComes) {
    zmq::context_t context;
    IdleTickActor actor(context);
    actor.Start();
    ASSERT_TRUE(
        WaitUntil([&] { return actor.ticks >= IdleTickActor::kBusyTicks; }, kTimerPeriod * 50));
    std::this_thread::sleep_for(kTimerPeriod * 20);
    EXPECT_EQ(actor.ticks, IdleTickActor::kBusyTicks) << "an idle timer ticked at its busy period";
    zmq::socket_t peer(context, zmq::socket_type::pair);
    peer.set(zmq::sockopt::linger, 0);
    peer.connect("inproc://idle");
    const auto sent = steady_clock::now();
    peer.send(zmq::str_buffer("wake"), zmq::send_flags::none);
    ASSERT_TRUE(
        WaitUntil([&] { return actor.ticks > IdleTickActor::kBusyTicks; }, milliseconds(2000)));
    EXPECT_LT(steady_clock::now() - sent, kMaxTimerLateness) << "the message did not wake it";
    EXPECT_EQ(actor.messages, 1);
    // Each message is read when its socket's descriptor signals, not at the loop's slow sweep of
    // every socket (a quarter second): kPings messages, each sent once the last was read.
    constexpr int kPings = 20;
    const auto pings = steady_clock::now();
    for (int k = 0; k < kPings; ++k) {
        peer.send(zmq::str_buffer("ping"), zmq::send_flags::none);
        ASSERT_TRUE(WaitUntil([&] { return actor.messages == 2 + k; }, milliseconds(2000)));
    }
    EXPECT_LT(steady_clock::now() - pings, milliseconds(1000))
        << "messages waited for the sweep, not their descriptor";
    actor.Stop();
}

/// Owns a socket itself (as a transport endpoint would) and polls it by handle.
class ForeignSocketActor final : public Actor {
  public:
    explicit ForeignSocketActor(zmq::context_t& context) : Actor("foreign", context) {}
    ~ForeignSocketActor() override { Stop(); }

    std::promise<std::string> got;
    bool released_on_actor_thread = false;

  protected:
    void OnStart() override {
        socket_.emplace(Context(), zmq::socket_type::pair);
        socket_->set(zmq::sockopt::linger, 0);
        socket_->bind("inproc://foreign");
        thread_ = std::this_thread::get_id();
        WatchReadable(socket_->handle(), [this] {
            zmq::message_t msg;
            while (socket_->recv(msg, zmq::recv_flags::dontwait)) {
                CountHandled();
                got.set_value(msg.to_string());
            }
        });
    }
    void OnStop() override {
        released_on_actor_thread = std::this_thread::get_id() == thread_;
        socket_.reset();
    }

  private:
    std::optional<zmq::socket_t> socket_;
    std::thread::id thread_;
};

TEST(Actor, PollsAForeignSocketByHandleAndReleasesItOnItsThread) {
    zmq::context_t context;
    ForeignSocketActor actor(context);
    std::future<std::string> got = actor.got.get_future();
    actor.Start();
    zmq::socket_t peer(context, zmq::socket_type::pair);
    peer.set(zmq::sockopt::linger, 0);
    peer.connect("inproc://foreign");
    peer.send(zmq::str_buffer("hello"));
    ASSERT_EQ(got.wait_for(kDeliveryTimeout), std::future_status::ready);
    EXPECT_EQ(got.get(), "hello");
    actor.Stop();
    EXPECT_TRUE(actor.released_on_actor_thread);
    EXPECT_EQ(actor.Counters().handled, 1u);
    peer.close();
    EXPECT_TRUE(ContextClosesWithin(context, kContextCloseTimeout));
}

class FailingStartActor final : public Actor {
  public:
    explicit FailingStartActor(zmq::context_t& context) : Actor("failing", context) {}
    ~FailingStartActor() override { Stop(); }

  protected:
    void OnStart() override {
        MakeSocket(zmq::socket_type::pull).bind("inproc://fails");
        throw std::invalid_argument("endpoint: bad on purpose");
    }
};

TEST(Actor, StartRethrowsWhatOnStartThrewAndClosesItsSockets) {
    zmq::context_t context;
    FailingStartActor actor(context);
    EXPECT_THROW(actor.Start(), std::invalid_argument);
    EXPECT_FALSE(actor.Running());
    EXPECT_TRUE(ContextClosesWithin(context, kContextCloseTimeout));  // its socket was closed
}

}  // namespace
}  // namespace certislam::actors
