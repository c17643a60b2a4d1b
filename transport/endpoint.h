// RAII ZeroMQ endpoint of a logical edge: typed send/receive of Message (envelope + zero-copy
// binary frames), per-edge queue policy, drop counters, and the hello/ready handshake.
#pragma once

#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>
#include <zmq.hpp>

#include "transport/endpoint_config.h"
#include "transport/message.h"
#include "transport/shm_buffer.h"
#include "transport/shm_edge.h"

namespace certislam::transport {

/// Counters of one endpoint (a snapshot; safe to read from another thread).
struct EndpointCounters {
    std::uint64_t sent = 0;               ///< messages handed to ZeroMQ
    std::uint64_t received = 0;           ///< valid messages accepted into the queue
    std::uint64_t dropped_malformed = 0;  ///< garbage, truncated, wrong frame count/size
    std::uint64_t dropped_version = 0;    ///< unknown schema major; a subscriber of the old framing
    std::uint64_t dropped_unauthorized = 0;  ///< header robot id != authenticated CURVE user id
    std::uint64_t dropped_queue_full = 0;    ///< kLatest: oldest dropped (receive) or send dropped
    std::uint64_t send_backpressure = 0;     ///< kReliable: Send gave up after send_timeout_ms
    std::uint64_t control_received = 0;      ///< handshake messages consumed by the endpoint
    std::uint64_t dropped_shm = 0;   ///< shm descriptor forged, malformed, stale or not on ipc
    std::uint64_t shm_received = 0;  ///< messages whose frames came through shm (mapped, no copy)
    std::uint64_t shm_lent = 0;      ///< frames sent from the producer's own segment (no copy)
    std::uint64_t shm_copied = 0;    ///< frames sent by one copy into a pooled segment
    std::uint64_t shm_copy_ns = 0;   ///< total time of those copies
    std::uint64_t shm_fallback = 0;  ///< large frames sent inline: no segment could be made
};

/// Outcome of a send.
enum class SendStatus {
    kSent,          ///< queued in ZeroMQ
    kDropped,       ///< kLatest edge, queue full: dropped and counted
    kBackpressure,  ///< kReliable edge, queue full for send_timeout_ms: not sent, retry later
    kUnroutable,    ///< ROUTER: no connected peer has that routing id
};

/// A publisher's messages travel behind a topic frame, which ZeroMQ filters at the publisher:
/// every subscriber subscribes to the broadcast topic and to its own robot's, so a message for
/// one robot (Endpoint::SendToRobot) is never sent to the others.
inline constexpr char kBroadcastTopic[] = "B";
/// The topic of the subscribers of robot `robot` ("R<robot>.": no robot's is a prefix of
/// another's).
std::string RobotTopic(std::uint32_t robot);

/// One socket of a logical edge. Owns the socket (linger 0); one thread uses it at a time.
/// For a mailbox: zmq_poll on handle() for ZMQ_POLLIN, then call Receive() until it returns
/// nullopt (the endpoint keeps a bounded queue of its own, which zmq_poll does not see).
class Endpoint {
  public:
    /// Creates, configures, binds and connects the socket. Throws std::invalid_argument on a
    /// bad config and zmq::error_t when ZeroMQ refuses an address.
    Endpoint(zmq::context_t& context, EndpointConfig config);
    ~Endpoint();
    Endpoint(const Endpoint&) = delete;
    Endpoint& operator=(const Endpoint&) = delete;

    /// Sends a message (publisher, dealer, push). Binary frames are not copied.
    SendStatus Send(const Message& message);
    /// Sends a message to one peer of a ROUTER (peer = Message::peer of one of its messages).
    SendStatus SendTo(std::string_view peer, const Message& message);
    /// Publisher: sends a message to the subscribers of robot `robot`'s topic only (ZeroMQ does
    /// not police who subscribes to it: the receiver still checks the message is for it). Its
    /// frames go inline, never through shm (the readers are not counted).
    SendStatus SendToRobot(std::uint32_t robot, const Message& message);

    /// A buffer for the producer to fill and Seal() into a frame of a message to send here. On
    /// an edge that uses shared memory (EndpointConfig::UsesShm) and for at least
    /// shm_threshold_bytes it lies in a segment, so Send lends it to the reader with no copy at
    /// all; otherwise (or when no segment can be made) it is private memory.
    WritableBuffer Allocate(std::size_t size);

    /// The next valid message, or nullopt when none is available now (never blocks). Bad
    /// messages met on the way are dropped and counted.
    std::optional<Message> Receive();
    /// The next valid message, waiting at most timeout.
    std::optional<Message> Receive(std::chrono::milliseconds timeout);

    /// Publisher: waits until `count` subscribers have said hello (a robot topic's subscription,
    /// which follows the broadcast one); answers each with a Ready on the stream. Returns false
    /// on timeout.
    bool WaitForSubscribers(std::size_t count, std::chrono::milliseconds timeout);
    /// Subscriber: waits for the publisher's Ready. Dealer: sends Hello, waits for the router's
    /// Ready (routers answer Hello by themselves). Returns false on timeout. Messages that
    /// arrive meanwhile stay queued for Receive().
    bool WaitReady(std::chrono::milliseconds timeout);
    /// True once the handshake completed (subscriber/dealer) or a subscriber joined (publisher).
    bool ready() const { return ready_; }
    /// Publisher: subscriptions currently known.
    std::size_t subscribers() const { return subscribers_; }

    /// The raw ZeroMQ socket handle, for zmq_poll.
    void* handle() { return socket_.handle(); }
    /// The socket itself.
    zmq::socket_t& socket() { return socket_; }
    /// Messages waiting in the endpoint's own queue.
    std::size_t queued() const { return queue_.size(); }
    /// Addresses actually bound (tcp port 0 resolved to the ephemeral port).
    const std::vector<std::string>& bound_addresses() const { return bound_; }
    /// The configuration it was built from.
    const EndpointConfig& config() const { return config_; }
    /// Snapshot of the counters.
    EndpointCounters counters() const;
    /// Connections refused by the connection caps (0 when the socket is not bound to tcp://).
    std::size_t refused_connections() const { return guard_ ? guard_->refused() : 0; }

  private:
    struct AtomicCounters {
        std::atomic<std::uint64_t> sent{0}, received{0}, dropped_malformed{0}, dropped_version{0},
            dropped_unauthorized{0}, dropped_queue_full{0}, send_backpressure{0},
            control_received{0}, dropped_shm{0}, shm_received{0}, shm_lent{0}, shm_copied{0},
            shm_copy_ns{0}, shm_fallback{0};
    };

    void Configure();
    void Pump();
    bool QueueHasRoom() const;
    void HandleFrames(std::vector<zmq::message_t>&& frames);
    void HandleSubscription(const zmq::message_t& frame);
    bool HandleControl(const Message& message);
    void Enqueue(Message&& message);
    SendStatus SendFrames(std::vector<zmq::message_t>&& frames);
    SendStatus SendMessage(const std::string* peer, const Message& message,
                           const std::string* topic = nullptr);
    bool ResolveShm(Message& message);
    Message MakeControl(std::uint64_t nonce, bool hello) const;

    EndpointConfig config_;
    std::string robot_topic_;  ///< RobotTopic(config_.robot_id), compared on every receive
    zmq::socket_t socket_;
    std::unique_ptr<ConnectionGuard> guard_;  ///< set when bound to tcp:// with caps
    std::vector<std::string> bound_;
    std::deque<Message> queue_;
    std::size_t queue_bytes_ = 0;
    AtomicCounters counters_;
    bool ready_ = false;
    std::size_t subscribers_ = 0;
    std::uint64_t hello_nonce_ = 0;
    std::uint64_t control_sequence_ = 0;
    std::unique_ptr<ShmLender> shm_lender_;      ///< set when the edge uses shm and sends
    std::unique_ptr<ShmResolver> shm_resolver_;  ///< set when the edge uses shm and receives
};

}  // namespace certislam::transport
