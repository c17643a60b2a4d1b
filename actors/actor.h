// Actor runtime: a mailbox loop on its own thread that polls its ZeroMQ sockets and Asio timers.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <deque>
#include <functional>
#include <future>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <boost/asio/io_context.hpp>
#include <boost/asio/steady_timer.hpp>
#include <zmq.hpp>

#include "transport/endpoint.h"

namespace certislam::actors {

/// A copy of an actor's counters at one instant (all monotonically increasing).
struct ActorCounters {
    uint64_t handled = 0;            ///< messages a handler accepted
    uint64_t dropped_malformed = 0;  ///< messages a handler rejected as malformed
    uint64_t handler_errors = 0;     ///< handler, timer or posted task exceptions caught
    uint64_t queue_full_drops = 0;   ///< sends that found the outgoing queue full
    uint64_t timer_fires = 0;        ///< timer callbacks run

    bool operator==(const ActorCounters&) const = default;
};

/// What a message handler did with one message.
enum class Disposition {
    kHandled,    ///< accepted (counted in `handled`)
    kMalformed,  ///< dropped as malformed (counted in `dropped_malformed`)
};

/// The frames of one multipart ZeroMQ message.
using Frames = std::vector<zmq::message_t>;

/// Handles one message received on a watched socket; may throw (counted, the actor keeps going).
using MessageHandler = std::function<Disposition(Frames& frames)>;

/// Called when a watched foreign socket (e.g. a transport endpoint) is readable; it receives
/// what it wants and reports with `Count*`. May throw (counted, the actor keeps going).
using ReadableHandler = std::function<void()>;

/// Handles one valid message taken from a watched transport endpoint; may throw (counted, the
/// actor keeps going). Malformed messages never reach it: the endpoint drops and counts them.
using EndpointHandler = std::function<void(transport::Message& message)>;

/// Base class of every actor. A derived class creates its sockets and timers in `OnStart()`
/// (which runs on the actor's thread: one socket per thread), and must call `Stop()` in its own
/// destructor. The loop waits in epoll on the watched sockets' ZMQ_FDs and a wake-up eventfd
/// with a timeout equal to the next timer deadline, reads the sockets that signalled (those it
/// also sends on at every wake-up, every socket in a slow sweep), then runs the io_context's
/// ready handlers.
class Actor {
  public:
    /// `context` must outlive the actor; inproc edges need both ends on the same context.
    Actor(std::string name, zmq::context_t& context);
    virtual ~Actor();

    Actor(const Actor&) = delete;
    Actor& operator=(const Actor&) = delete;

    /// Starts the thread and returns once `OnStart()` has run there (so its sockets are bound);
    /// rethrows what `OnStart()` threw. Calling it on a running actor is a programmer error.
    void Start();

    /// Wakes the loop, runs `OnStop()` on the actor's thread, closes the sockets it owns and
    /// joins. Returns without waiting for queued messages; a no-op when not running.
    void Stop();

    /// Asks the loop to end after the handler that runs now (thread-safe; from the actor's own
    /// thread too), without joining: a team asks every actor first, then joins each.
    void RequestStop();

    /// Runs `task` on the actor's thread at the next loop iteration (thread-safe; exceptions
    /// are counted as handler errors). A task that posts again runs again only after a poll,
    /// so a chain of posts cannot starve the sockets. Tasks pending at stop are dropped.
    void Post(std::function<void()> task);

    /// True once a stop was asked (thread-safe): long handlers may poll it to end early.
    bool StopRequested() const { return stop_requested_.load(std::memory_order_acquire); }

    /// True between `Start()` and `Stop()`.
    bool Running() const { return thread_.joinable(); }

    /// The actor's name (for logs).
    const std::string& Name() const { return name_; }

    /// The counters now (thread-safe).
    ActorCounters Counters() const;

  protected:
    /// Runs on the actor's thread before the loop: create sockets, watches and timers here.
    virtual void OnStart() = 0;
    /// Runs on the actor's thread after the loop: release foreign sockets here.
    virtual void OnStop() {}

    /// A socket owned by the runtime (linger 0), closed on the actor's thread at stop.
    /// Actor thread only; the reference stays valid until the actor stops.
    zmq::socket_t& MakeSocket(zmq::socket_type type);

    /// Polls `socket` and calls `handler` for each multipart message received on it.
    void Watch(zmq::socket_t& socket, MessageHandler handler);

    /// Polls a transport endpoint (which the derived class owns, creates in OnStart() and
    /// destroys in OnStop()) and calls `handler` for each valid message; counts `handled`.
    /// Drains the endpoint's own queue too, which the socket's descriptor does not show.
    void WatchEndpoint(transport::Endpoint& endpoint, EndpointHandler handler);

    /// Polls a foreign socket by its libzmq handle and calls `handler` when it is readable.
    void WatchReadable(void* zmq_socket_handle, ReadableHandler handler);

    /// Calls `tick` every `period`, first one `period` from now, on a fixed cadence (a late
    /// tick does not shift the next ones; ticks missed entirely are skipped). Actor thread only.
    void Every(std::chrono::nanoseconds period, std::function<void()> tick);

    /// Calls `tick` every `period` while it returns true (busy); after it returns false, every
    /// `idle_period` (>= period) until the actor dispatches a message or a posted task, which
    /// brings the next tick within `period` again. For ticks whose work comes with messages: an
    /// idle actor of a large team in one process then wakes rarely. Actor thread only.
    void EveryUntilIdle(std::chrono::nanoseconds period, std::chrono::nanoseconds idle_period,
                        std::function<bool()> tick);

    /// Calls `task` once after `delay`. Actor thread only.
    void After(std::chrono::nanoseconds delay, std::function<void()> task);

    /// Sends `frames` without blocking; counts a queue-full drop and returns false when the
    /// socket's queue is full (EAGAIN). Other failures throw zmq::error_t.
    bool SendOrDrop(zmq::socket_t& socket, Frames& frames);

    /// Counters for handlers that receive by themselves (`WatchReadable`).
    void CountHandled(uint64_t n = 1) { handled_.fetch_add(n, std::memory_order_relaxed); }
    void CountMalformed(uint64_t n = 1) { malformed_.fetch_add(n, std::memory_order_relaxed); }
    void CountQueueFull(uint64_t n = 1) { queue_full_.fetch_add(n, std::memory_order_relaxed); }

    /// The ZeroMQ context the actor's sockets live in.
    zmq::context_t& Context() { return context_; }

  private:
    struct WatchEntry;
    struct TimerEntry;

    void ThreadMain(std::promise<void>* started);
    void Loop();
    void Dispatch(WatchEntry& watch);
    void DispatchEndpoint(WatchEntry& watch);
    long PollTimeoutMs() const;
    void ArmTimer(TimerEntry& timer);
    void AddWatch(std::unique_ptr<WatchEntry> entry);
    static bool Readable(const WatchEntry& watch);  ///< a message waits (ZMQ_EVENTS)
    /// The epoll wait: 0 when a watch is due, else until the next timer or sweep.
    long WaitMs(std::chrono::steady_clock::time_point next_sweep) const;
    bool ReadDue();  ///< dispatches the due watches that hold a message; true when any did
    /// Idle timers (EveryUntilIdle) fire within their busy period again.
    void WakeIdleTimers();
    void Wake();
    void DrainWake();
    void RunGuarded(const std::function<void()>& fn);
    void RunPostedTasks();
    void Teardown();
    bool OnActorThread() const { return std::this_thread::get_id() == thread_id_; }

    std::string name_;
    zmq::context_t& context_;
    int wake_fd_ = -1;
    int epoll_fd_ = -1;  ///< the run's epoll set: the wake-up eventfd and each watch's ZMQ_FD
    std::thread thread_;
    std::thread::id thread_id_;
    std::atomic<bool> stop_requested_{false};
    boost::asio::io_context io_;
    std::deque<zmq::socket_t> owned_sockets_;
    std::vector<std::unique_ptr<WatchEntry>> watches_;
    std::vector<std::unique_ptr<TimerEntry>> timers_;
    std::mutex tasks_mutex_;
    std::vector<std::function<void()>> tasks_;  ///< posted, guarded by tasks_mutex_

    std::atomic<uint64_t> handled_{0};
    std::atomic<uint64_t> malformed_{0};
    std::atomic<uint64_t> handler_errors_{0};
    std::atomic<uint64_t> queue_full_{0};
    std::atomic<uint64_t> timer_fires_{0};
};

}  // namespace certislam::actors
