// Actor runtime: the poll loop, timers, start/stop and counters.
#include "actors/actor.h"

#include <pthread.h>
#include <sys/eventfd.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <exception>
#include <iterator>
#include <optional>
#include <stdexcept>
#include <utility>

#include <zmq_addon.hpp>

#include "slam/core/check.h"

namespace certislam::actors {

namespace {

/// Messages taken from one socket per wake-up, so that one busy socket cannot starve the
/// others, the timers or a stop request.
constexpr int kMaxBatch = 64;

}  // namespace

struct Actor::WatchEntry {
    void* handle = nullptr;                   ///< libzmq socket handle polled
    zmq::socket_t* socket = nullptr;          ///< set for `Watch`: the runtime receives
    MessageHandler on_message;                ///< for `Watch`
    ReadableHandler on_readable;              ///< for `WatchReadable`
    transport::Endpoint* endpoint = nullptr;  ///< set for `WatchEndpoint`
    EndpointHandler on_endpoint;              ///< for `WatchEndpoint`
};

struct Actor::TimerEntry {
    TimerEntry(boost::asio::io_context& io, std::chrono::nanoseconds p, std::function<void()> f)
        : timer(io), period(p), fn(std::move(f)) {}
    boost::asio::steady_timer timer;
    std::chrono::nanoseconds period;  ///< zero: one-shot
    std::function<void()> fn;
    bool done = false;  ///< a one-shot that has fired
};

Actor::Actor(std::string name, zmq::context_t& context)
    : name_(std::move(name)), context_(context) {
    wake_fd_ = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
    if (wake_fd_ < 0) throw std::runtime_error("actor " + name_ + ": eventfd failed");
}

Actor::~Actor() {
    // A derived class must call Stop() in its destructor: OnStop() is virtual.
    CERTISLAM_CHECK(!thread_.joinable());
    ::close(wake_fd_);
}

void Actor::Start() {
    CERTISLAM_CHECK(!thread_.joinable());
    stop_requested_.store(false, std::memory_order_release);
    std::promise<void> started;
    std::future<void> ready = started.get_future();
    thread_ = std::thread([this, &started] { ThreadMain(&started); });
    try {
        ready.get();
    } catch (...) {
        thread_.join();
        throw;
    }
}

void Actor::Stop() {
    if (!thread_.joinable()) return;
    CERTISLAM_CHECK(!OnActorThread());  // an actor cannot join itself: use RequestStop()
    stop_requested_.store(true, std::memory_order_release);
    Wake();
    thread_.join();
}

void Actor::RequestStop() {
    stop_requested_.store(true, std::memory_order_release);
    Wake();
}

void Actor::Post(std::function<void()> task) {
    {
        const std::lock_guard<std::mutex> lock(tasks_mutex_);
        tasks_.push_back(std::move(task));
    }
    Wake();
}

ActorCounters Actor::Counters() const {
    ActorCounters c;
    c.handled = handled_.load(std::memory_order_relaxed);
    c.dropped_malformed = malformed_.load(std::memory_order_relaxed);
    c.handler_errors = handler_errors_.load(std::memory_order_relaxed);
    c.queue_full_drops = queue_full_.load(std::memory_order_relaxed);
    c.timer_fires = timer_fires_.load(std::memory_order_relaxed);
    return c;
}

zmq::socket_t& Actor::MakeSocket(zmq::socket_type type) {
    CERTISLAM_CHECK(OnActorThread());
    zmq::socket_t& socket = owned_sockets_.emplace_back(context_, type);
    socket.set(zmq::sockopt::linger, 0);
    return socket;
}

void Actor::Watch(zmq::socket_t& socket, MessageHandler handler) {
    CERTISLAM_CHECK(OnActorThread());
    auto entry = std::make_unique<WatchEntry>();
    entry->handle = socket.handle();
    entry->socket = &socket;
    entry->on_message = std::move(handler);
    watches_.push_back(std::move(entry));
}

void Actor::WatchEndpoint(transport::Endpoint& endpoint, EndpointHandler handler) {
    CERTISLAM_CHECK(OnActorThread());
    auto entry = std::make_unique<WatchEntry>();
    entry->handle = endpoint.handle();
    entry->endpoint = &endpoint;
    entry->on_endpoint = std::move(handler);
    WatchEntry* watch = entry.get();
    watches_.push_back(std::move(entry));
    // Messages may already wait in the endpoint's queue (taken in during a handshake).
    Post([this, watch] { Dispatch(*watch); });
}

void Actor::WatchReadable(void* zmq_socket_handle, ReadableHandler handler) {
    CERTISLAM_CHECK(OnActorThread());
    CERTISLAM_CHECK(zmq_socket_handle != nullptr);
    auto entry = std::make_unique<WatchEntry>();
    entry->handle = zmq_socket_handle;
    entry->on_readable = std::move(handler);
    watches_.push_back(std::move(entry));
}

void Actor::Every(std::chrono::nanoseconds period, std::function<void()> tick) {
    CERTISLAM_CHECK(OnActorThread());
    CERTISLAM_CHECK(period.count() > 0);
    auto& timer = *timers_.emplace_back(std::make_unique<TimerEntry>(io_, period, std::move(tick)));
    timer.timer.expires_after(period);
    ArmTimer(timer);
}

void Actor::After(std::chrono::nanoseconds delay, std::function<void()> task) {
    CERTISLAM_CHECK(OnActorThread());
    auto& timer = *timers_.emplace_back(
        std::make_unique<TimerEntry>(io_, std::chrono::nanoseconds{0}, std::move(task)));
    timer.timer.expires_after(delay);
    ArmTimer(timer);
}

bool Actor::SendOrDrop(zmq::socket_t& socket, Frames& frames) {
    if (zmq::send_multipart(socket, frames, zmq::send_flags::dontwait)) return true;
    CountQueueFull();
    return false;
}

void Actor::ThreadMain(std::promise<void>* started) {
    thread_id_ = std::this_thread::get_id();
    // `top -H` and perf show the actor (Linux keeps 15 characters).
    pthread_setname_np(pthread_self(), Name().substr(0, 15).c_str());
    try {
        OnStart();
    } catch (...) {
        Teardown();
        started->set_exception(std::current_exception());
        return;
    }
    started->set_value();  // `started` lives in Start(): not touched after this line
    Loop();
    Teardown();
}

void Actor::Loop() {
    std::vector<zmq_pollitem_t> items;
    while (!stop_requested_.load(std::memory_order_acquire)) {
        items.clear();
        items.push_back({nullptr, wake_fd_, ZMQ_POLLIN, 0});
        for (const auto& watch : watches_) items.push_back({watch->handle, 0, ZMQ_POLLIN, 0});
        const int rc = zmq_poll(items.data(), static_cast<int>(items.size()), PollTimeoutMs());
        if (rc < 0) {
            CERTISLAM_CHECK(zmq_errno() == EINTR);  // ETERM: context closed under a live actor
            continue;
        }
        if ((items[0].revents & ZMQ_POLLIN) != 0) DrainWake();
        for (size_t i = 1; i < items.size(); ++i) {
            if (stop_requested_.load(std::memory_order_acquire)) break;
            if ((items[i].revents & ZMQ_POLLIN) != 0) Dispatch(*watches_[i - 1]);
        }
        RunPostedTasks();
        io_.restart();
        io_.poll();
        std::erase_if(timers_, [](const auto& timer) { return timer->done; });
    }
}

void Actor::Dispatch(WatchEntry& watch) {
    if (watch.endpoint != nullptr) {
        DispatchEndpoint(watch);
        return;
    }
    if (watch.socket == nullptr) {
        RunGuarded(watch.on_readable);
        return;
    }
    for (int i = 0; i < kMaxBatch && !StopRequested(); ++i) {
        Frames frames;
        if (!zmq::recv_multipart(*watch.socket, std::back_inserter(frames),
                                 zmq::recv_flags::dontwait)) {
            return;  // drained
        }
        std::optional<Disposition> disposition;
        RunGuarded([&] { disposition = watch.on_message(frames); });
        if (disposition == Disposition::kHandled) {
            CountHandled();
        } else if (disposition == Disposition::kMalformed) {
            CountMalformed();
        }
    }
}

void Actor::DispatchEndpoint(WatchEntry& watch) {
    for (int i = 0; i < kMaxBatch && !StopRequested(); ++i) {
        std::optional<transport::Message> message = watch.endpoint->Receive();
        if (!message) return;
        bool ok = false;
        RunGuarded([&] {
            watch.on_endpoint(*message);
            ok = true;
        });
        if (ok) CountHandled();
    }
    // Batch used up: what is left may sit in the endpoint's queue, which zmq_poll does not see.
    if (watch.endpoint->queued() > 0 && !StopRequested())
        Post([this, w = &watch] { Dispatch(*w); });
}

long Actor::PollTimeoutMs() const {
    if (stop_requested_.load(std::memory_order_acquire)) return 0;
    std::optional<std::chrono::steady_clock::time_point> earliest;
    for (const auto& timer : timers_) {
        if (timer->done) continue;
        const auto expiry = timer->timer.expiry();
        if (!earliest || expiry < *earliest) earliest = expiry;
    }
    if (!earliest) return -1;  // no timer: wait for a message or a wake-up
    const auto wait = *earliest - std::chrono::steady_clock::now();
    if (wait.count() <= 0) return 0;
    return static_cast<long>(std::chrono::ceil<std::chrono::milliseconds>(wait).count());
}

void Actor::ArmTimer(TimerEntry& timer) {
    // The handler touches `timer` only when not aborted: an aborted wait means the entry is
    // being destroyed (Teardown).
    timer.timer.async_wait([this, &timer](const boost::system::error_code& ec) {
        if (ec) return;
        timer_fires_.fetch_add(1, std::memory_order_relaxed);
        RunGuarded(timer.fn);
        if (timer.period.count() == 0) {
            timer.done = true;
            return;
        }
        auto next = timer.timer.expiry() + timer.period;
        const auto now = std::chrono::steady_clock::now();
        if (next <= now) next += ((now - next) / timer.period + 1) * timer.period;
        timer.timer.expires_at(next);
        ArmTimer(timer);
    });
}

void Actor::Wake() {
    const uint64_t one = 1;
    // EAGAIN only when the counter is saturated, in which case the loop is woken anyway.
    [[maybe_unused]] const ssize_t n = ::write(wake_fd_, &one, sizeof(one));
}

void Actor::DrainWake() {
    uint64_t count = 0;
    [[maybe_unused]] const ssize_t n = ::read(wake_fd_, &count, sizeof(count));
}

void Actor::RunGuarded(const std::function<void()>& fn) {
    try {
        fn();
    } catch (const std::exception& e) {
        if (handler_errors_.fetch_add(1, std::memory_order_relaxed) == 0) {
            std::fprintf(stderr, "actor %s: handler error (logged once): %s\n", name_.c_str(),
                         e.what());
        }
    } catch (...) {
        if (handler_errors_.fetch_add(1, std::memory_order_relaxed) == 0) {
            std::fprintf(stderr, "actor %s: handler error (logged once): unknown\n", name_.c_str());
        }
    }
}

void Actor::RunPostedTasks() {
    std::vector<std::function<void()>> tasks;
    {
        const std::lock_guard<std::mutex> lock(tasks_mutex_);
        tasks.swap(tasks_);
    }
    for (const auto& task : tasks) {
        if (StopRequested()) return;  // a stop drops pending tasks, as Teardown would
        RunGuarded(task);
    }
}

void Actor::Teardown() {
    RunGuarded([this] { OnStop(); });
    timers_.clear();  // cancels pending waits; their aborted handlers run below
    io_.restart();
    io_.poll();
    watches_.clear();
    owned_sockets_.clear();  // linger 0: closes at once
    const std::lock_guard<std::mutex> lock(tasks_mutex_);
    tasks_.clear();
}

}  // namespace certislam::actors
