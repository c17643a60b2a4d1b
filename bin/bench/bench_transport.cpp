// `certislam bench transport [--json]`: one-way latency and throughput of a large buffer over
// inproc (zero-copy handle), ipc (shared memory, descriptor on an ipc:// socket, two processes),
// tcp loopback (two processes) and ipc with the bytes on the socket, beside a plain memcpy.
//
// Every transport runs the same sender and receiver code over transport::Endpoint (PUSH/PULL):
// the sender stamps CLOCK_MONOTONIC (the same clock in every process of the host) and sends; the
// receiver spins briefly on a non-blocking Receive, then blocks in zmq_poll, stamps the arrival,
// reads the first and last byte of the buffer, and acknowledges on a second edge. Latency: median
// of arrival - send, one message in flight. Throughput: a window of messages in flight, bytes /
// (last ack - first send). For ipc-shm the latency includes the sender's copy into the segment;
// latency_beyond_copy_us is the median, message by message, of the latency minus that copy.
#include <sys/wait.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "bin/command.h"
#include "certislam/v1/control.pb.h"
#include "certislam/v1/keyframe.pb.h"
#include "transport/endpoint.h"
#include "transport/shm_buffer.h"

namespace certislam::bin {
namespace {

using transport::Endpoint;
using transport::EndpointConfig;
using transport::Message;
using transport::SharedBuffer;

std::int64_t NowNs() {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(
               std::chrono::steady_clock::now().time_since_epoch())
        .count();
}

/// How the buffer crosses the edge.
/// Both ipc-shm modes go through the Endpoint's own shared-memory path of an ipc:// edge.
/// kIpcShmLoan: the producer wrote its bytes in a segment (Endpoint::Allocate), so nothing is
/// copied; kIpcShm sends a private buffer, which the Endpoint copies into a pooled segment.
enum class Mode { kInproc, kIpcShm, kIpcShmLoan, kIpcSocket, kTcp };

const char* ModeName(Mode mode) {
    switch (mode) {
        case Mode::kInproc:
            return "inproc";
        case Mode::kIpcShm:
            return "ipc-shm";
        case Mode::kIpcShmLoan:
            return "ipc-shm-loan";
        case Mode::kIpcSocket:
            return "ipc-socket";
        case Mode::kTcp:
            return "tcp";
    }
    return "?";
}

struct Row {
    std::string transport;
    std::size_t bytes = 0;
    double latency_us = 0;
    double throughput_gbps = 0;  // 1e9 bytes per second
    /// ipc-shm: median of (latency - the sender's own copy into the segment) per message.
    std::optional<double> beyond_copy_us;
};

struct Plan {
    std::size_t bytes = 0;
    int latency_messages = 0;
    int throughput_messages = 0;
    int window = 1;
};

double Median(std::vector<double> values) {
    std::sort(values.begin(), values.end());
    return values.empty() ? 0.0 : values[values.size() / 2];
}

EndpointConfig EdgeConfig(const char* edge, transport::Role role, const std::string& address,
                          bool bind, int socket_buffer_bytes = 0) {
    EndpointConfig config;
    config.edge = edge;
    config.role = role;
    (bind ? config.bind : config.connect).push_back(address);
    config.delivery = transport::Delivery::kReliable;
    config.send_timeout_ms = 30000;
    config.max_queue_bytes = std::size_t{2} << 30;
    config.socket_buffer_bytes = socket_buffer_bytes;
    return config;
}

// Polls a non-blocking Receive for up to kSpinNs (busy polling, as iceoryx does), yielding the
// core between polls so that two waiting sides do not starve each other on a loaded machine,
// then blocks in zmq_poll.
constexpr std::int64_t kSpinNs = 20'000'000;

// Where the bytes go through the socket (tcp, ipc-socket), ZeroMQ's I/O thread of each process
// does the copying: a spinning application thread would take the core it needs on a 2-core
// machine, so those receivers block in zmq_poll at once (spin 0).
std::int64_t SpinNs(Mode mode) {
    return mode == Mode::kTcp || mode == Mode::kIpcSocket ? 0 : kSpinNs;
}

Message SpinReceive(Endpoint& endpoint, std::int64_t spin_ns) {
    const std::int64_t spin_until = NowNs() + spin_ns;
    while (NowNs() < spin_until) {
        if (auto message = endpoint.Receive()) return std::move(*message);
        std::this_thread::yield();
    }
    if (auto message = endpoint.Receive(std::chrono::milliseconds(60'000))) {
        return std::move(*message);
    }
    throw std::runtime_error("bench transport: nothing received for 60 s");
}

// The receiver: acknowledges every buffer with its arrival time until a Shutdown arrives.
void ReceiverLoop(zmq::context_t& context, const std::string& data_address,
                  const std::string& ack_address, int socket_buffer_bytes, std::int64_t spin_ns) {
    Endpoint data(context, EdgeConfig("bench", transport::Role::kPull, data_address, false,
                                      socket_buffer_bytes));
    Endpoint ack(context, EdgeConfig("bench-ack", transport::Role::kPush, ack_address, false));
    v1::Heartbeat hello;
    ack.Send(transport::Pack(hello));
    while (true) {
        v1::Heartbeat reply;  // carries the first and last byte back: the bytes were read
        std::uint64_t sequence = 0;
        std::int64_t arrived = 0;
        {
            // Over ipc a large frame arrives as a view of the sender's shared-memory segment
            // (the Endpoint maps the descriptor); it is released before the ack so the sender
            // may reuse the segment.
            const Message message = SpinReceive(data, spin_ns);
            arrived = NowNs();
            if (message.Is<v1::Shutdown>()) return;
            const auto keyframe = transport::Unpack<v1::Keyframe>(message);
            if (!keyframe || message.frames.size() != 1) {
                throw std::runtime_error("bad bench message");
            }
            const std::span<const std::byte> bytes = message.frames[0].span();
            reply.set_period_ms(std::to_integer<std::uint32_t>(bytes.front()) << 8 |
                                std::to_integer<std::uint32_t>(bytes.back()));
            sequence = keyframe->header().sequence();
        }
        reply.mutable_header()->set_sequence(sequence);
        reply.mutable_header()->set_stamp_ns(arrived);
        ack.Send(transport::Pack(reply));
    }
}

// The sender's data edge: ipc-socket is ipc with the Endpoint's shared-memory path turned off.
EndpointConfig DataConfig(Mode mode, const std::string& address, int socket_buffer_bytes) {
    EndpointConfig config =
        EdgeConfig("bench", transport::Role::kPush, address, true, socket_buffer_bytes);
    config.shm_enabled = mode != Mode::kIpcSocket;
    return config;
}

// The sending side of one transport: bound endpoints, the buffer, the producer's shm buffers.
class Sender {
  public:
    Sender(zmq::context_t& context, Mode mode, const std::string& data_address,
           const std::string& ack_address, int socket_buffer_bytes = 0)
        : mode_(mode),
          data_(context, DataConfig(mode, data_address, socket_buffer_bytes)),
          ack_(context, EdgeConfig("bench-ack", transport::Role::kPull, ack_address, true)) {}

    std::string data_address() const { return data_.bound_addresses().front(); }
    std::string ack_address() const { return ack_.bound_addresses().front(); }
    void WaitReceiver() { SpinReceive(ack_, SpinNs(mode_)); }

    Row Run(const Plan& plan) {
        Prepare(plan);
        // Warm-up: a full window in flight, so the Endpoint's segment pool is made (and its
        // pages faulted in) before anything is timed.
        for (int i = 0; i < plan.window; ++i) Send(plan.bytes, i);
        for (int i = 0; i < plan.window; ++i) Ack();
        for (int i = 0; i < 3; ++i) Send(plan.bytes, i % plan.window), Ack();
        std::vector<double> latencies;
        std::vector<double> beyond_copy;
        for (int i = 0; i < plan.latency_messages; ++i) {
            const std::int64_t sent = Send(plan.bytes, i % plan.window);
            latencies.push_back(static_cast<double>(Ack().header().stamp_ns() - sent) * 1e-3);
            beyond_copy.push_back(latencies.back() - static_cast<double>(copy_ns_) * 1e-3);
        }
        const std::int64_t start = NowNs();
        int in_flight = 0;
        for (int i = 0; i < plan.throughput_messages; ++i) {
            if (in_flight == plan.window) Ack(), --in_flight;
            Send(plan.bytes, i % plan.window);
            ++in_flight;
        }
        while (in_flight-- > 0) Ack();
        const double seconds = static_cast<double>(NowNs() - start) * 1e-9;
        loans_.clear();
        Row row{ModeName(mode_),
                plan.bytes,
                Median(latencies),
                static_cast<double>(plan.bytes) * plan.throughput_messages / seconds * 1e-9,
                {}};
        if (mode_ == Mode::kIpcShm) row.beyond_copy_us = Median(beyond_copy);
        return row;
    }

    void Shutdown() { data_.Send(transport::Pack(v1::Shutdown{})); }

  private:
    void Prepare(const Plan& plan) {
        std::vector<std::byte> bytes(plan.bytes);
        for (std::size_t i = 0; i < bytes.size(); ++i) bytes[i] = std::byte(i * 131u + 7u);
        source_ = SharedBuffer::Adopt(std::move(bytes));
        loans_.clear();
        if (mode_ != Mode::kIpcShmLoan) return;
        // The producer writes its bytes where the Endpoint can lend them (shared memory on this
        // ipc edge), once per slot of the window; sending them again copies nothing.
        for (int i = 0; i < plan.window; ++i) {
            transport::WritableBuffer buffer = data_.Allocate(plan.bytes);
            std::memcpy(buffer.bytes().data(), source_.data(), plan.bytes);
            loans_.push_back(buffer.Seal());
        }
    }

    // Sends one buffer and returns its send stamp. ipc-shm: the Endpoint copies the private
    // buffer into a pooled segment (timed by its shm_copy_ns counter); ipc-shm-loan: the buffer
    // of `slot` already lies in shared memory; the others: a handle, copied only by the socket.
    std::int64_t Send(std::size_t bytes, int slot) {
        v1::Keyframe keyframe;
        keyframe.mutable_header()->set_sequence(sequence_++);
        const std::int64_t sent = NowNs();
        keyframe.mutable_header()->set_stamp_ns(sent);
        Message message = transport::Pack(keyframe);
        const bool loan = mode_ == Mode::kIpcShmLoan;
        transport::AppendFrame(message, loan ? loans_[static_cast<std::size_t>(slot)] : source_);
        const std::uint64_t copy_before = data_.counters().shm_copy_ns;
        if (data_.Send(message) != transport::SendStatus::kSent) {
            throw std::runtime_error("bench transport: send failed");
        }
        copy_ns_ = static_cast<std::int64_t>(data_.counters().shm_copy_ns - copy_before);
        if (bytes != message.frames[0].size()) throw std::logic_error("bench transport: size");
        return sent;
    }

    v1::Heartbeat Ack() {
        auto ack = transport::Unpack<v1::Heartbeat>(SpinReceive(ack_, SpinNs(mode_)));
        const std::uint32_t expected =
            std::to_integer<std::uint32_t>(source_.data()[0]) << 8 |
            std::to_integer<std::uint32_t>(source_.data()[source_.size() - 1]);
        if (!ack || ack->period_ms() != expected) {
            throw std::runtime_error("bench transport: bad ack (bytes not read back)");
        }
        return *ack;
    }

    Mode mode_;
    Endpoint data_;
    Endpoint ack_;
    SharedBuffer source_;
    std::vector<SharedBuffer> loans_;  // ipc-shm-loan: the producer's buffers in shared memory
    std::uint64_t sequence_ = 0;
    std::int64_t copy_ns_ = 0;  // the last Send's copy into shared memory
};

std::vector<Row> RunAll(Sender& sender, const std::vector<Plan>& plans) {
    std::vector<Row> rows;
    rows.reserve(plans.size());
    sender.WaitReceiver();
    for (const auto& plan : plans) rows.push_back(sender.Run(plan));
    sender.Shutdown();
    return rows;
}

std::vector<Row> RunInproc(const std::vector<Plan>& plans) {
    zmq::context_t context;
    Sender sender(context, Mode::kInproc, "inproc://bench-data", "inproc://bench-ack");
    std::exception_ptr failure;
    std::thread receiver([&] {
        try {
            ReceiverLoop(context, "inproc://bench-data", "inproc://bench-ack", 0, kSpinNs);
        } catch (...) {
            failure = std::current_exception();
        }
    });
    std::vector<Row> rows = RunAll(sender, plans);
    receiver.join();
    if (failure) std::rethrow_exception(failure);
    return rows;
}

// Two processes: the child (forked before either side makes a ZeroMQ context) reads the
// addresses the parent bound from a pipe, then runs the receiver.
std::vector<Row> RunTwoProcesses(Mode mode, const std::vector<Plan>& plans,
                                 int socket_buffer_bytes) {
    const auto dir =
        std::filesystem::temp_directory_path() / ("certislam-bench-" + std::to_string(getpid()));
    std::filesystem::create_directories(dir);
    int fds[2];
    if (pipe(fds) != 0) throw std::runtime_error("pipe failed");
    const pid_t child = fork();
    if (child < 0) throw std::runtime_error("fork failed");
    if (child == 0) {
        close(fds[1]);
        char text[1024] = {};
        std::size_t got = 0;
        while (got < sizeof(text) - 1) {
            const ssize_t n = read(fds[0], text + got, sizeof(text) - 1 - got);
            if (n <= 0) break;
            got += static_cast<std::size_t>(n);
        }
        const std::string both(text, got);
        const auto split = both.find('\n');
        int status = 0;
        try {
            zmq::context_t context;
            ReceiverLoop(context, both.substr(0, split), both.substr(split + 1),
                         socket_buffer_bytes, SpinNs(mode));
        } catch (const std::exception& e) {
            std::fprintf(stderr, "bench transport receiver: %s\n", e.what());
            status = 1;
        }
        _exit(status);
    }
    close(fds[0]);
    const bool tcp = mode == Mode::kTcp;
    std::vector<Row> rows;
    {
        zmq::context_t context;
        Sender sender(context, mode, tcp ? "tcp://127.0.0.1:*" : "ipc://" + (dir / "data").string(),
                      tcp ? "tcp://127.0.0.1:*" : "ipc://" + (dir / "ack").string(),
                      socket_buffer_bytes);
        const std::string both = sender.data_address() + "\n" + sender.ack_address();
        if (write(fds[1], both.data(), both.size()) != static_cast<ssize_t>(both.size())) {
            throw std::runtime_error("pipe write failed");
        }
        close(fds[1]);
        rows = RunAll(sender, plans);
    }
    int status = 0;
    waitpid(child, &status, 0);
    std::filesystem::remove_all(dir);
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
        throw std::runtime_error(std::string("bench transport: receiver failed over ") +
                                 ModeName(mode));
    }
    return rows;
}

Row RunMemcpy(const Plan& plan) {
    std::vector<std::byte> source(plan.bytes, std::byte{1});
    std::vector<std::byte> target(plan.bytes, std::byte{0});
    std::vector<double> times;
    for (int i = 0; i < plan.latency_messages + 3; ++i) {
        source[static_cast<std::size_t>(i) % plan.bytes] = std::byte(i);
        const std::int64_t start = NowNs();
        std::memcpy(target.data(), source.data(), plan.bytes);
        const std::int64_t stop = NowNs();
        if (target[static_cast<std::size_t>(i) % plan.bytes] != std::byte(i))
            throw std::logic_error("memcpy");
        if (i >= 3) times.push_back(static_cast<double>(stop - start) * 1e-3);
    }
    const double us = Median(times);
    return Row{"memcpy", plan.bytes, us, static_cast<double>(plan.bytes) / us * 1e-3, {}};
}

std::vector<Plan> MakePlans(std::size_t max_bytes, double scale) {
    const std::vector<Plan> all = {{1u << 10, 2000, 4000, 4},
                                   {1u << 20, 300, 300, 4},
                                   {10u << 20, 60, 60, 4},
                                   {100u << 20, 9, 9, 2}};
    std::vector<Plan> plans;
    for (Plan plan : all) {
        if (plan.bytes > max_bytes) continue;
        plan.latency_messages = std::max(3, static_cast<int>(plan.latency_messages * scale));
        plan.throughput_messages = std::max(3, static_cast<int>(plan.throughput_messages * scale));
        plans.push_back(plan);
    }
    return plans;
}

void Print(const std::vector<Row>& rows, bool json) {
    if (json) {
        nlohmann::json out = nlohmann::json::array();
        for (const auto& row : rows) {
            out.push_back({{"transport", row.transport},
                           {"bytes", row.bytes},
                           {"latency_us", row.latency_us},
                           {"throughput_gbps", row.throughput_gbps}});
            if (row.beyond_copy_us) out.back()["latency_beyond_copy_us"] = *row.beyond_copy_us;
        }
        std::printf("%s\n", out.dump(2).c_str());
        return;
    }
    std::printf("%-13s %12s %14s %16s %16s\n", "transport", "bytes", "latency_us",
                "throughput_GB/s", "beyond_copy_us");
    for (const auto& row : rows) {
        std::printf("%-13s %12zu %14.2f %16.3f", row.transport.c_str(), row.bytes, row.latency_us,
                    row.throughput_gbps);
        if (row.beyond_copy_us) std::printf(" %16.2f", *row.beyond_copy_us);
        std::printf("\n");
    }
}

int RunTransportBench(int argc, char** argv) {
    CLI::App app{
        "One-way latency (median) and throughput (GB/s = 1e9 bytes/s) of 1 KB..100 MB buffers "
        "over inproc (zero-copy), ipc-shm (shared memory, two processes), ipc-socket, tcp "
        "loopback (two processes), and memcpy"};
    app.name("certislam bench transport");
    bool json = false;
    std::size_t max_bytes = 100u << 20;
    double scale = 1.0;
    app.add_flag("--json", json,
                 "print a JSON list of {transport, bytes, latency_us, throughput_gbps}");
    app.add_option("--max-bytes", max_bytes, "largest buffer size to run");
    app.add_option("--scale", scale, "multiply the message counts (e.g. 0.1 for a quick run)")
        ->check(CLI::PositiveNumber);
    int socket_buffer_bytes = EndpointConfig{}.socket_buffer_bytes;
    app.add_option("--socket-buffer-bytes", socket_buffer_bytes,
                   "ZMQ_SNDBUF/ZMQ_RCVBUF of the data edge (0: OS default, autotuned)")
        ->capture_default_str()
        ->check(CLI::NonNegativeNumber);
    std::vector<std::string> only;
    app.add_option("--only", only,
                   "run only these transports (inproc ipc-shm ipc-shm-loan "
                   "ipc-socket tcp; memcpy always runs)");
    CLI11_PARSE(app, argc, argv);
    const auto wanted = [&](Mode mode) {
        return only.empty() || std::find(only.begin(), only.end(), ModeName(mode)) != only.end();
    };

    const std::vector<Plan> plans = MakePlans(max_bytes, scale);
    std::vector<Row> rows;
    rows.reserve(plans.size() * 6);
    for (const auto& plan : plans) rows.push_back(RunMemcpy(plan));
    if (wanted(Mode::kInproc)) {
        for (auto& row : RunInproc(plans)) rows.push_back(row);
    }
    for (Mode mode : {Mode::kIpcShm, Mode::kIpcShmLoan, Mode::kIpcSocket, Mode::kTcp}) {
        if (!wanted(mode)) continue;
        for (auto& row : RunTwoProcesses(mode, plans, socket_buffer_bytes)) rows.push_back(row);
    }
    Print(rows, json);
    return 0;
}

const BenchRegistrar kRegistrar{
    "transport", "one-way latency and throughput: inproc, ipc-shm, tcp, memcpy", RunTransportBench};

}  // namespace
}  // namespace certislam::bin
