// Actor runtime: the poll loop, timers, start/stop and counters.
#include "actors/actor.h"

#include <pthread.h>
#include <sys/epoll.h>
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
/// Every watch is checked this often even when its descriptor did not signal (Loop).
constexpr std::chrono::milliseconds kSweepPeriod{250};
constexpr int kMaxEvents = 64;                         ///< descriptors taken from epoll per wake-up
constexpr std::uint64_t kWakeTag = ~std::uint64_t{0};  ///< epoll data of the wake-up eventfd

}  // namespace

struct Actor::WatchEntry {
    void* handle = nullptr;                   ///< libzmq socket handle polled
    zmq::socket_t* socket = nullptr;          ///< set for `Watch`: the runtime receives
    MessageHandler on_message;                ///< for `Watch`
    ReadableHandler on_readable;              ///< for `WatchReadable`
    transport::Endpoint* endpoint = nullptr;  ///< set for `WatchEndpoint`
    EndpointHandler on_endpoint;              ///< for `WatchEndpoint`
    bool due = false;                         ///< to be checked at this wake-up (Loop)
    /// The actor may send on it too (not SUB or PULL): a send takes the descriptor's signal
    bool two_way = true;
};

struct Actor::TimerEntry {
    TimerEntry(boost::asio::io_context& io, std::chrono::nanoseconds p, std::function<void()> f)
        : timer(io), period(p), fn(std::move(f)) {}
    boost::asio::steady_timer timer;
    std::chrono::nanoseconds period;  ///< zero: one-shot
    std::function<void()> fn;
    bool done = false;  ///< a one-shot that has fired
    /// EveryUntilIdle: the period while idle (zero: never idle), and whether the last tick was
    std::chrono::nanoseconds idle_period{0};
    bool idle = false;
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
    AddWatch(std::move(entry));
}

void Actor::WatchEndpoint(transport::Endpoint& endpoint, EndpointHandler handler) {
    CERTISLAM_CHECK(OnActorThread());
    auto entry = std::make_unique<WatchEntry>();
    entry->handle = endpoint.handle();
    entry->endpoint = &endpoint;
    entry->on_endpoint = std::move(handler);
    WatchEntry* watch = entry.get();
    AddWatch(std::move(entry));
    // Messages may already wait in the endpoint's queue (taken in during a handshake).
    Post([this, watch] { Dispatch(*watch); });
}

void Actor::WatchReadable(void* zmq_socket_handle, ReadableHandler handler) {
    CERTISLAM_CHECK(OnActorThread());
    CERTISLAM_CHECK(zmq_socket_handle != nullptr);
    auto entry = std::make_unique<WatchEntry>();
    entry->handle = zmq_socket_handle;
    entry->on_readable = std::move(handler);
    AddWatch(std::move(entry));
}

// The loop waits on each socket's ZMQ_FD through epoll, so a wake-up costs the sockets that
// signalled, not all of them: zmq_poll checks every socket with two system calls, and a solver
// watches a socket per peer and stream. The descriptor signals that the socket's state may have
// changed; ZMQ_EVENTS says whether a message waits.
void Actor::AddWatch(std::unique_ptr<WatchEntry> entry) {
    int fd = -1, type = -1;
    std::size_t size = sizeof(fd), type_size = sizeof(type);
    if (zmq_getsockopt(entry->handle, ZMQ_FD, &fd, &size) != 0 ||
        zmq_getsockopt(entry->handle, ZMQ_TYPE, &type, &type_size) != 0) {
        throw std::runtime_error("actor " + name_ +
                                 ": ZMQ_FD failed: " + zmq_strerror(zmq_errno()));
    }
    entry->two_way = type != ZMQ_SUB && type != ZMQ_PULL;
    epoll_event event{};
    event.events = EPOLLIN;
    event.data.u64 = watches_.size();
    if (::epoll_ctl(epoll_fd_, EPOLL_CTL_ADD, fd, &event) != 0) {
        throw std::runtime_error("actor " + name_ + ": epoll_ctl failed");
    }
    entry->due = true;  // a message may wait already
    watches_.push_back(std::move(entry));
}

bool Actor::Readable(const WatchEntry& watch) {
    int events = 0;
    std::size_t size = sizeof(events);
    if (zmq_getsockopt(watch.handle, ZMQ_EVENTS, &events, &size) != 0) {
        // ETERM: context closed under a live actor (its descriptor would stay readable)
        CERTISLAM_CHECK(zmq_errno() == EINTR);
        return false;
    }
    return (events & ZMQ_POLLIN) != 0;
}

long Actor::WaitMs(std::chrono::steady_clock::time_point next_sweep) const {
    const bool due =
        std::any_of(watches_.begin(), watches_.end(), [](const auto& watch) { return watch->due; });
    const long timeout = due ? 0 : PollTimeoutMs();
    const long to_sweep = std::max<long>(0, std::chrono::ceil<std::chrono::milliseconds>(
                                                next_sweep - std::chrono::steady_clock::now())
                                                .count());
    return timeout < 0 || timeout > to_sweep ? to_sweep : timeout;
}

bool Actor::ReadDue() {
    bool read = false;
    // By index: a handler may add a watch (the entries stay, the vector may move).
    for (std::size_t i = 0; i < watches_.size(); ++i) {
        if (stop_requested_.load(std::memory_order_acquire)) break;
        WatchEntry& watch = *watches_[i];
        if (!watch.due) continue;
        watch.due = false;
        if (!Readable(watch)) continue;
        read = true;
        Dispatch(watch);
        watch.due = Readable(watch);  // a batch left messages: again at once
    }
    return read;
}

void Actor::Every(std::chrono::nanoseconds period, std::function<void()> tick) {
    CERTISLAM_CHECK(OnActorThread());
    CERTISLAM_CHECK(period.count() > 0);
    auto& timer = *timers_.emplace_back(std::make_unique<TimerEntry>(io_, period, std::move(tick)));
    timer.timer.expires_after(period);
    ArmTimer(timer);
}

void Actor::EveryUntilIdle(std::chrono::nanoseconds period, std::chrono::nanoseconds idle_period,
                           std::function<bool()> tick) {
    CERTISLAM_CHECK(OnActorThread());
    CERTISLAM_CHECK(period.count() > 0 && idle_period >= period);
    auto& timer = *timers_.emplace_back(std::make_unique<TimerEntry>(io_, period, nullptr));
    timer.idle_period = idle_period;
    timer.fn = [entry = &timer, tick = std::move(tick)] {
        entry->idle = false;  // a tick that throws counts as busy
        entry->idle = !tick();
    };
    timer.timer.expires_after(period);
    ArmTimer(timer);
}

void Actor::WakeIdleTimers() {
    const auto now = std::chrono::steady_clock::now();
    for (const auto& timer : timers_) {
        if (!timer->idle || timer->done) continue;
        timer->idle = false;
        const auto soon = now + timer->period;
        if (timer->timer.expiry() <= soon) continue;
        timer->timer.expires_at(soon);  // cancels the idle wait (its handler sees the abort)
        ArmTimer(*timer);
    }
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
    // One epoll set per run: a socket closed in the last run may linger in libzmq's reaper.
    epoll_fd_ = ::epoll_create1(EPOLL_CLOEXEC);
    epoll_event wake{};
    wake.events = EPOLLIN;
    wake.data.u64 = kWakeTag;
    if (epoll_fd_ < 0 || ::epoll_ctl(epoll_fd_, EPOLL_CTL_ADD, wake_fd_, &wake) != 0) {
        if (epoll_fd_ >= 0) ::close(epoll_fd_);
        epoll_fd_ = -1;
        started->set_exception(
            std::make_exception_ptr(std::runtime_error("actor " + name_ + ": epoll failed")));
        return;
    }
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
    std::vector<epoll_event> events(kMaxEvents);
    auto next_sweep = std::chrono::steady_clock::now() + kSweepPeriod;
    while (!stop_requested_.load(std::memory_order_acquire)) {
        // A send on a two-way socket (the last wake-up's handlers, tasks and ticks) may have taken
        // its descriptor's signal of a message that waits: those few are checked every time.
        for (auto& watch : watches_) {
            if (watch->two_way && !watch->due) watch->due = Readable(*watch);
        }
        const int n = ::epoll_wait(epoll_fd_, events.data(), kMaxEvents,
                                   static_cast<int>(WaitMs(next_sweep)));
        if (n < 0) {
            CERTISLAM_CHECK(errno == EINTR);
            continue;
        }
        bool woke = false;
        for (int k = 0; k < n; ++k) {
            if (events[k].data.u64 == kWakeTag) {
                DrainWake();
                woke = true;
            } else if (events[k].data.u64 < watches_.size()) {
                watches_[events[k].data.u64]->due = true;
            }
        }
        // Any other signal lost in libzmq must not leave a message waiting: a slow sweep.
        if (std::chrono::steady_clock::now() >= next_sweep) {
            for (auto& watch : watches_) watch->due = true;
            next_sweep = std::chrono::steady_clock::now() + kSweepPeriod;
        }
        woke = ReadDue() || woke;
        if (woke) WakeIdleTimers();  // a message or a posted task: work may be due
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
    // Batch used up: what is left may sit in the endpoint's queue, which the descriptor does not
    // show.
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
    // being destroyed (Teardown) or re-armed sooner (WakeIdleTimers), which waits anew.
    timer.timer.async_wait([this, &timer](const boost::system::error_code& ec) {
        if (ec) return;
        timer_fires_.fetch_add(1, std::memory_order_relaxed);
        RunGuarded(timer.fn);
        if (timer.period.count() == 0) {
            timer.done = true;
            return;
        }
        const auto step = timer.idle ? timer.idle_period : timer.period;
        auto next = timer.timer.expiry() + step;
        const auto now = std::chrono::steady_clock::now();
        if (next <= now) next += ((now - next) / step + 1) * step;
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
    ::close(epoll_fd_);
    epoll_fd_ = -1;
    const std::lock_guard<std::mutex> lock(tasks_mutex_);
    tasks_.clear();
}

}  // namespace certislam::actors
