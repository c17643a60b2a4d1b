// RAII ZeroMQ endpoint: socket options per role and policy, strict receive with drop counters,
// zero-copy send, and the hello/ready handshake.
#include "transport/endpoint.h"

#include <algorithm>
#include <cstring>
#include <iterator>
#include <stdexcept>
#include <zmq_addon.hpp>

#include "certislam/v1/control.pb.h"

namespace certislam::transport {

namespace {

zmq::socket_type SocketType(Role role) {
    switch (role) {
        case Role::kPublisher:
            return zmq::socket_type::xpub;
        case Role::kSubscriber:
            return zmq::socket_type::sub;
        case Role::kDealer:
            return zmq::socket_type::dealer;
        case Role::kRouter:
            return zmq::socket_type::router;
        case Role::kPush:
            return zmq::socket_type::push;
        case Role::kPull:
            return zmq::socket_type::pull;
    }
    return zmq::socket_type::pair;
}

bool Receives(Role role) { return role != Role::kPush; }

int ClampInt(std::size_t value) {
    return value > static_cast<std::size_t>(INT32_MAX) ? INT32_MAX : static_cast<int>(value);
}

}  // namespace

std::string RobotTopic(std::uint32_t robot) {
    std::string topic(1, 'R');
    topic += std::to_string(robot);
    topic += '.';
    return topic;
}

Endpoint::Endpoint(zmq::context_t& context, EndpointConfig config)
    : config_(std::move(config)), socket_(context, SocketType(config_.role)) {
    config_.Validate();
    robot_topic_ = RobotTopic(config_.robot_id);
    Configure();
    const auto is_tcp = [](const std::string& a) { return a.rfind("tcp://", 0) == 0; };
    const ConnectionCaps& caps = config_.connection_caps;
    if (std::any_of(config_.bind.begin(), config_.bind.end(), is_tcp) &&
        (caps.max_total > 0 || caps.max_per_peer > 0)) {
        guard_ = std::make_unique<ConnectionGuard>(context, socket_, caps);
    }
    for (const auto& address : config_.bind) {
        socket_.bind(address);
        bound_.push_back(socket_.get(zmq::sockopt::last_endpoint));
    }
    for (const auto& address : config_.connect) socket_.connect(address);
    if (config_.UsesShm()) {
        if (config_.role != Role::kPull && config_.role != Role::kSubscriber) {
            shm_lender_ = std::make_unique<ShmLender>(config_.shm, config_.shm_threshold_bytes,
                                                      config_.shm_pool_segments);
        }
        if (Receives(config_.role)) shm_resolver_ = std::make_unique<ShmResolver>(config_.shm);
    }
}

Endpoint::~Endpoint() = default;

void Endpoint::Configure() {
    socket_.set(zmq::sockopt::linger, 0);
    socket_.set(zmq::sockopt::sndhwm, ClampInt(config_.max_queue_messages));
    socket_.set(zmq::sockopt::rcvhwm, ClampInt(config_.max_queue_messages));
    socket_.set(zmq::sockopt::reconnect_ivl, config_.reconnect_interval_ms);
    socket_.set(zmq::sockopt::handshake_ivl, config_.handshake_timeout_ms);
    socket_.set(zmq::sockopt::backlog, config_.listen_backlog);
    if (config_.socket_buffer_bytes > 0) {
        socket_.set(zmq::sockopt::sndbuf, config_.socket_buffer_bytes);
        socket_.set(zmq::sockopt::rcvbuf, config_.socket_buffer_bytes);
    }
    const std::size_t max_frame =
        std::max(config_.limits.max_envelope_bytes, config_.limits.max_frame_bytes);
    socket_.set(zmq::sockopt::maxmsgsize, static_cast<int64_t>(max_frame));
    if (config_.delivery == Delivery::kReliable) {
        socket_.set(zmq::sockopt::sndtimeo, config_.send_timeout_ms);
    }
    switch (config_.role) {
        case Role::kPublisher:
            socket_.set(zmq::sockopt::xpub_verbose, 1);  // every subscriber's hello reaches us
            socket_.set(zmq::sockopt::xpub_nodrop, 1);   // full queue: EAGAIN, counted, not silent
            break;
        case Role::kSubscriber:
            socket_.set(zmq::sockopt::subscribe, kBroadcastTopic);
            socket_.set(zmq::sockopt::subscribe, robot_topic_);
            break;
        case Role::kRouter:
            socket_.set(zmq::sockopt::router_mandatory, 1);
            break;
        default:
            break;
    }
    if (config_.curve) ApplyCurve(socket_, *config_.curve);
}

EndpointCounters Endpoint::counters() const {
    EndpointCounters c;
    c.sent = counters_.sent.load();
    c.received = counters_.received.load();
    c.dropped_malformed = counters_.dropped_malformed.load();
    c.dropped_version = counters_.dropped_version.load();
    c.dropped_unauthorized = counters_.dropped_unauthorized.load();
    c.dropped_queue_full = counters_.dropped_queue_full.load();
    c.send_backpressure = counters_.send_backpressure.load();
    c.control_received = counters_.control_received.load();
    c.dropped_shm = counters_.dropped_shm.load();
    c.shm_received = counters_.shm_received.load();
    c.shm_lent = counters_.shm_lent.load();
    c.shm_copied = counters_.shm_copied.load();
    c.shm_copy_ns = counters_.shm_copy_ns.load();
    c.shm_fallback = counters_.shm_fallback.load();
    return c;
}

WritableBuffer Endpoint::Allocate(std::size_t size) {
    if (shm_lender_ != nullptr && size >= config_.shm_threshold_bytes) {
        auto buffer = WritableBuffer::Shm(size, config_.shm);
        if (buffer.ok()) return std::move(*buffer.value);
    }
    return WritableBuffer::Heap(size);
}

SendStatus Endpoint::Send(const Message& message) {
    if (config_.role == Role::kPublisher) Pump();  // take in subscriptions first
    return SendMessage(nullptr, message);
}

SendStatus Endpoint::SendTo(std::string_view peer, const Message& message) {
    const std::string id(peer);
    return SendMessage(&id, message);
}

SendStatus Endpoint::SendToRobot(std::uint32_t robot, const Message& message) {
    if (config_.role != Role::kPublisher)
        throw std::logic_error("Endpoint::SendToRobot: " + config_.edge + " is not a publisher");
    Pump();  // take in subscriptions first
    const std::string topic = RobotTopic(robot);
    return SendMessage(nullptr, message, &topic);
}

SendStatus Endpoint::SendMessage(const std::string* peer, const Message& message,
                                 const std::string* topic) {
    // A publisher lends one reference per subscriber; the other roles deliver to one peer.
    const bool publisher = config_.role == Role::kPublisher;
    const int readers = publisher ? ClampInt(subscribers_) : 1;
    ShmLoans loans;
    std::optional<Message> wire;
    if (shm_lender_ != nullptr && readers > 0 && topic == nullptr && shm_lender_->Wants(message)) {
        wire = message;  // the envelope and frame handles; the bytes are not copied here
        ShmLendStats stats;
        shm_lender_->Lend(*wire, readers, loans, stats);
        counters_.shm_lent.fetch_add(stats.lent);
        counters_.shm_copied.fetch_add(stats.copied);
        counters_.shm_copy_ns.fetch_add(stats.copy_ns);
        counters_.shm_fallback.fetch_add(stats.fallback);
    }
    std::vector<zmq::message_t> frames;
    if (peer != nullptr) frames.emplace_back(peer->data(), peer->size());
    if (publisher) {
        const std::string_view t =
            topic != nullptr ? std::string_view(*topic) : std::string_view(kBroadcastTopic);
        frames.emplace_back(t.data(), t.size());
    }
    auto body = Encode(wire ? *wire : message);
    std::move(body.begin(), body.end(), std::back_inserter(frames));
    const SendStatus status = SendFrames(std::move(frames));
    if (status != SendStatus::kSent) loans.Revoke();  // nobody will open those descriptors
    return status;
}

SendStatus Endpoint::SendFrames(std::vector<zmq::message_t>&& frames) {
    const bool latest = config_.delivery == Delivery::kLatest;
    const auto first_flags = latest ? zmq::send_flags::dontwait : zmq::send_flags::none;
    for (std::size_t i = 0; i < frames.size(); ++i) {
        const bool more = i + 1 < frames.size();
        auto flags = i == 0 ? first_flags : zmq::send_flags::none;
        if (more) flags = flags | zmq::send_flags::sndmore;
        zmq::send_result_t sent;
        try {
            sent = socket_.send(frames[i], flags);
        } catch (const zmq::error_t& e) {
            if (e.num() == EHOSTUNREACH) return SendStatus::kUnroutable;
            throw;
        }
        if (!sent) {
            // ZeroMQ accepts the rest of a multipart message once its first frame is accepted.
            if (latest) {
                counters_.dropped_queue_full.fetch_add(1);
                return SendStatus::kDropped;
            }
            counters_.send_backpressure.fetch_add(1);
            return SendStatus::kBackpressure;
        }
    }
    counters_.sent.fetch_add(1);
    return SendStatus::kSent;
}

std::optional<Message> Endpoint::Receive() {
    Pump();
    if (queue_.empty()) return std::nullopt;
    Message message = std::move(queue_.front());
    queue_.pop_front();
    queue_bytes_ -= message.ByteSize();
    return message;
}

std::optional<Message> Endpoint::Receive(std::chrono::milliseconds timeout) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (true) {
        if (auto message = Receive()) return message;
        const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
            deadline - std::chrono::steady_clock::now());
        if (left.count() < 0) return std::nullopt;
        zmq::pollitem_t item{socket_.handle(), 0, ZMQ_POLLIN, 0};
        zmq::poll(&item, 1, left);
        if (!(item.revents & ZMQ_POLLIN) && left.count() == 0) return std::nullopt;
    }
}

bool Endpoint::QueueHasRoom() const {
    return queue_.size() < config_.max_queue_messages && queue_bytes_ < config_.max_queue_bytes;
}

void Endpoint::Pump() {
    if (!Receives(config_.role)) return;
    while (config_.delivery == Delivery::kLatest || QueueHasRoom()) {
        std::vector<zmq::message_t> frames;
        if (!zmq::recv_multipart(socket_, std::back_inserter(frames), zmq::recv_flags::dontwait)) {
            return;
        }
        HandleFrames(std::move(frames));
    }
}

void Endpoint::HandleFrames(std::vector<zmq::message_t>&& frames) {
    if (config_.role == Role::kPublisher) {
        if (frames.size() == 1) HandleSubscription(frames[0]);
        return;  // publishers take nothing else in
    }
    std::string peer;
    if (config_.role == Role::kRouter && !frames.empty()) {
        peer = frames.front().to_string();
        frames.erase(frames.begin());
    }
    std::string user_id;
    if (config_.curve && !frames.empty()) {
        if (const char* user = zmq_msg_gets(frames.front().handle(), "User-Id")) user_id = user;
    }
    if (config_.role == Role::kSubscriber) {  // the topic frame: broadcast or this robot's
        const std::string_view topic =
            frames.empty() ? std::string_view() : frames.front().to_string_view();
        if (frames.size() < 2 || (topic != kBroadcastTopic && topic != robot_topic_)) {
            counters_.dropped_malformed.fetch_add(1);
            return;
        }
        frames.erase(frames.begin());
    }
    DecodeResult result = Decode(std::move(frames), config_.limits);
    if (result.status == DecodeResult::Status::kUnsupportedVersion) {
        counters_.dropped_version.fetch_add(1);
        return;
    }
    if (result.status != DecodeResult::Status::kOk) {
        counters_.dropped_malformed.fetch_add(1);
        return;
    }
    Message message = std::move(*result.message);
    // A CURVE peer is named by its key; its messages must not claim another robot's id.
    if (config_.curve && config_.curve->server &&
        user_id != std::to_string(message.envelope.header().robot_id())) {
        counters_.dropped_unauthorized.fetch_add(1);
        return;
    }
    message.peer = std::move(peer);
    message.user_id = std::move(user_id);
    if (!ResolveShm(message)) return;
    if (HandleControl(message)) return;
    Enqueue(std::move(message));
}

bool Endpoint::ResolveShm(Message& message) {
    if (!HasShmFrames(message)) return true;
    std::string detail;
    // Descriptors are honoured only on an ipc-only edge: a tcp peer cannot name this host's
    // segments, and a forged one must not take references meant for a local reader.
    if (shm_resolver_ == nullptr || !shm_resolver_->Resolve(message, detail)) {
        counters_.dropped_shm.fetch_add(1);
        return false;
    }
    counters_.shm_received.fetch_add(1);
    return true;
}

void Endpoint::HandleSubscription(const zmq::message_t& frame) {
    // A subscriber subscribes to the broadcast topic, then to its robot's ("R<digits>."): the
    // second is its hello, because one pipe keeps their order, so both filters are in by then
    // and a SendToRobot right after WaitForSubscribers reaches it.
    const auto* bytes = static_cast<const char*>(frame.data());
    const std::string_view topic =
        frame.size() > 0 ? std::string_view(bytes + 1, frame.size() - 1) : std::string_view();
    const bool robot_topic = topic.size() >= 3 && topic.front() == 'R' && topic.back() == '.' &&
                             std::all_of(topic.begin() + 1, topic.end() - 1,
                                         [](char c) { return c >= '0' && c <= '9'; });
    const auto kind = frame.size() > 0 ? static_cast<std::uint8_t>(bytes[0]) : std::uint8_t{2};
    // A subscription to everything is a subscriber from before the topic frame: it would drop
    // every message as malformed, so it is counted as of another wire version, not as a hello.
    if (kind == 1 && topic.empty()) counters_.dropped_version.fetch_add(1);
    if (!robot_topic) return;
    if (kind == 1) {
        ++subscribers_;
        ready_ = true;
        counters_.control_received.fetch_add(1);
        SendMessage(nullptr, MakeControl(0, false));  // the subscriber's WaitReady takes it
    } else if (kind == 0 && subscribers_ > 0) {
        --subscribers_;
    }
}

bool Endpoint::HandleControl(const Message& message) {
    if (config_.role == Role::kRouter && message.Is<v1::Hello>()) {
        const auto hello = Unpack<v1::Hello>(message);
        if (!hello) return false;
        Message ready = MakeControl(hello->nonce(), false);
        SendTo(message.peer, ready);
        counters_.control_received.fetch_add(1);
        return false;  // the application still sees who said hello
    }
    if ((config_.role == Role::kSubscriber || config_.role == Role::kDealer) &&
        message.Is<v1::Ready>()) {
        const auto ready = Unpack<v1::Ready>(message);
        if (ready && (config_.role == Role::kSubscriber || ready->nonce() == hello_nonce_)) {
            ready_ = true;
        }
        counters_.control_received.fetch_add(1);
        return true;
    }
    return false;
}

void Endpoint::Enqueue(Message&& message) {
    const std::size_t bytes = message.ByteSize();
    if (config_.delivery == Delivery::kLatest) {
        while (!queue_.empty() && (queue_.size() >= config_.max_queue_messages ||
                                   queue_bytes_ + bytes > config_.max_queue_bytes)) {
            queue_bytes_ -= queue_.front().ByteSize();
            queue_.pop_front();
            counters_.dropped_queue_full.fetch_add(1);
        }
        if (bytes > config_.max_queue_bytes) {
            counters_.dropped_queue_full.fetch_add(1);
            return;
        }
    }
    queue_bytes_ += bytes;
    queue_.push_back(std::move(message));
    counters_.received.fetch_add(1);
}

Message Endpoint::MakeControl(std::uint64_t nonce, bool hello) const {
    v1::Header header;
    header.set_robot_id(config_.robot_id);
    header.set_stamp_ns(std::chrono::duration_cast<std::chrono::nanoseconds>(
                            std::chrono::system_clock::now().time_since_epoch())
                            .count());
    if (hello) {
        v1::Hello message;
        *message.mutable_header() = header;
        message.set_node_name(config_.node_name);
        message.set_edge_name(config_.edge);
        message.set_nonce(nonce);
        return Pack(message);
    }
    v1::Ready message;
    *message.mutable_header() = header;
    message.set_node_name(config_.node_name);
    message.set_edge_name(config_.edge);
    message.set_nonce(nonce);
    return Pack(message);
}

bool Endpoint::WaitForSubscribers(std::size_t count, std::chrono::milliseconds timeout) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (subscribers_ < count) {
        Pump();
        if (subscribers_ >= count) break;
        const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
            deadline - std::chrono::steady_clock::now());
        if (left.count() <= 0) return false;
        zmq::pollitem_t item{socket_.handle(), 0, ZMQ_POLLIN, 0};
        zmq::poll(&item, 1, left);
    }
    return true;
}

bool Endpoint::WaitReady(std::chrono::milliseconds timeout) {
    if (config_.role == Role::kDealer) {
        hello_nonce_ = (reinterpret_cast<std::uintptr_t>(this) << 16) ^ ++control_sequence_;
        ready_ = false;
        if (SendFrames(Encode(MakeControl(hello_nonce_, true))) != SendStatus::kSent) {
            return false;
        }
    }
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (!ready_) {
        const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
            deadline - std::chrono::steady_clock::now());
        if (left.count() <= 0) return false;
        zmq::pollitem_t item{socket_.handle(), 0, ZMQ_POLLIN, 0};
        zmq::poll(&item, 1, left);
        Pump();
    }
    return true;
}

}  // namespace certislam::transport
