// Endpoint over a real ipc:// socket between two processes routes large frames through shared
// memory by itself: exact bytes, the receiver's frame points into its read-only mapping (never
// copied), segments reclaimed after release and after SIGKILL, forged descriptors dropped.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>

#include "tests/transport/test_util.h"
#include "transport/endpoint.h"
#include "transport/shm_buffer.h"

namespace certislam::transport {
namespace {

using testing::Config;
using testing::TempDir;
using testing::TestMessage;

constexpr std::chrono::milliseconds kTimeout{10000};
constexpr std::size_t kHeapBytes = (std::size_t{3} << 20) + 13;  ///< copied into a pooled segment
constexpr std::size_t kLoanBytes = (std::size_t{2} << 20) + 7;   ///< written in shm by producer
constexpr std::size_t kSmallBytes = 1000;                        ///< under the threshold: inline

std::string Prefix() { return "cstep" + std::to_string(::getpid()); }

EndpointConfig IpcConfig(Role role, const std::string& address, bool bind,
                         const std::string& prefix) {
    EndpointConfig config = Config(role, address, bind);
    config.send_timeout_ms = static_cast<int>(kTimeout.count());
    config.shm.prefix = prefix;
    return config;
}

std::byte PatternByte(std::size_t i, unsigned seed) {
    return static_cast<std::byte>((i * 131 + seed) % 251);
}

void Fill(std::span<std::byte> bytes, unsigned seed) {
    for (std::size_t i = 0; i < bytes.size(); ++i) bytes[i] = PatternByte(i, seed);
}

bool Matches(std::span<const std::byte> bytes, unsigned seed) {
    for (std::size_t i = 0; i < bytes.size(); ++i) {
        if (bytes[i] != PatternByte(i, seed)) return false;
    }
    return true;
}

/// The file of this process's mapping that contains address ("" when none does).
std::string MappingOf(const void* address) {
    const auto at = reinterpret_cast<std::uintptr_t>(address);
    std::ifstream maps("/proc/self/maps");
    std::string line;
    while (std::getline(maps, line)) {
        std::istringstream fields(line);
        std::string range, perms, offset, device, inode, path;
        fields >> range >> perms >> offset >> device >> inode >> path;
        const auto dash = range.find('-');
        const auto begin = std::stoull(range.substr(0, dash), nullptr, 16);
        const auto end = std::stoull(range.substr(dash + 1), nullptr, 16);
        if (at >= begin && at < end) return path + " " + perms;
    }
    return "";
}

void WriteLine(int fd, const std::string& text) {
    const std::string line = text + "\n";
    if (::write(fd, line.data(), line.size()) != static_cast<ssize_t>(line.size())) ::_exit(9);
}

std::string ReadLine(int fd) {
    std::string line;
    char c = 0;
    while (::read(fd, &c, 1) == 1 && c != '\n') line += c;
    return line;
}

/// Exit status of a child (-signal when it was killed by one).
int WaitChild(pid_t pid) {
    int status = 0;
    EXPECT_EQ(::waitpid(pid, &status, 0), pid);
    if (WIFSIGNALED(status)) return -WTERMSIG(status);
    return WEXITSTATUS(status);
}

/// Receives one message and reports "<mapping of frame 0> <perms> <bytes ok>".
std::string Describe(Endpoint& pull, std::optional<Message>& held, unsigned seed) {
    held = pull.Receive(kTimeout);
    if (!held || held->frames.size() != 1) return "nothing";
    const SharedBuffer& frame = held->frames[0];
    return MappingOf(frame.data()) + " " + (Matches(frame.span(), seed) ? "same" : "different");
}

/// The child: receives three messages, reports each, holds them until told, then releases.
[[noreturn]] void ReceiverChild(const std::string& address, const std::string& prefix, int report,
                                int go) {
    int code = 0;
    {
        zmq::context_t context;
        Endpoint pull(context, IpcConfig(Role::kPull, address, false, prefix));
        std::optional<Message> heap, loan, small;
        WriteLine(report, Describe(pull, heap, 1));
        WriteLine(report, Describe(pull, loan, 2));
        WriteLine(report, Describe(pull, small, 3));
        WriteLine(report, std::to_string(pull.counters().shm_received));
        if (ReadLine(go) != "release") code = 4;
    }  // the messages, the mappings and the endpoint are gone here
    WriteLine(report, "released");
    ::_exit(code);
}

struct Child {
    pid_t pid = 0;
    int report = -1;  ///< read end
    int go = -1;      ///< write end
};

Child StartReceiver(const std::string& address, const std::string& prefix) {
    int report[2], go[2];
    EXPECT_EQ(::pipe(report), 0);
    EXPECT_EQ(::pipe(go), 0);
    const pid_t pid = ::fork();
    if (pid == 0) {
        ::close(report[0]);
        ::close(go[1]);
        ReceiverChild(address, prefix, report[1], go[0]);
    }
    ::close(report[1]);
    ::close(go[0]);
    return Child{pid, report[0], go[1]};
}

/// The shm segment name in a Describe line ("/dev/shm/<name> ..." -> "/<name>").
std::string SegmentName(const std::string& line) {
    const std::string head = "/dev/shm";
    if (line.rfind(head, 0) != 0) return "";
    return line.substr(head.size(), line.find(' ') - head.size());
}

TEST(ShmEndpoint, LargeFramesCrossProcessesThroughSharedMemoryWithoutReceiverCopy) {
    const TempDir dir;
    const std::string address = "ipc://" + dir.path() + "/shm-edge";
    const std::string prefix = Prefix();
    Child child = StartReceiver(address, prefix);  // forked before any ZeroMQ context
    std::string heap_segment, loan_segment;
    {
        zmq::context_t context;
        Endpoint push(context, IpcConfig(Role::kPush, address, true, prefix));
        std::vector<std::byte> heap_bytes(kHeapBytes);
        Fill(heap_bytes, 1);
        ASSERT_EQ(push.Send(TestMessage(1, 1, {SharedBuffer::Adopt(std::move(heap_bytes))})),
                  SendStatus::kSent);
        WritableBuffer loan = push.Allocate(kLoanBytes);
        ASSERT_TRUE(loan.in_shm());
        Fill(loan.bytes(), 2);
        SharedBuffer sealed = loan.Seal();
        ASSERT_EQ(push.Send(TestMessage(2, 1, {sealed})), SendStatus::kSent);
        std::vector<std::byte> small_bytes(kSmallBytes);
        Fill(small_bytes, 3);
        ASSERT_EQ(push.Send(TestMessage(3, 1, {SharedBuffer::Adopt(std::move(small_bytes))})),
                  SendStatus::kSent);

        const std::string heap = ReadLine(child.report);
        const std::string lent = ReadLine(child.report);
        const std::string small = ReadLine(child.report);
        EXPECT_EQ(ReadLine(child.report), "2");  // messages that came through shared memory
        // The receiver's bytes lie in a read-only mapping of a segment of this edge's family.
        EXPECT_EQ(heap.rfind("/dev/shm/" + prefix + "-", 0), 0u) << heap;
        EXPECT_NE(heap.find(" r--s same"), std::string::npos) << heap;
        EXPECT_EQ(lent.rfind("/dev/shm/" + prefix + "-", 0), 0u) << lent;
        EXPECT_NE(lent.find(" r--s same"), std::string::npos) << lent;
        EXPECT_EQ(small.find("/dev/shm"), std::string::npos) << small;  // inline on the socket
        EXPECT_NE(small.find(" same"), std::string::npos) << small;
        heap_segment = SegmentName(heap);
        loan_segment = SegmentName(lent);
        EXPECT_EQ(loan_segment, sealed.shm_segment()->name());
        const EndpointCounters counters = push.counters();
        EXPECT_EQ(counters.shm_copied, 1u);
        EXPECT_EQ(counters.shm_lent, 1u);
        EXPECT_EQ(counters.shm_fallback, 0u);

        sealed = SharedBuffer();  // the producer lets go; the child still holds it
        EXPECT_TRUE(ShmSegmentExists(loan_segment));
        WriteLine(child.go, "release");
        EXPECT_EQ(ReadLine(child.report), "released");
        EXPECT_EQ(WaitChild(child.pid), 0);
        EXPECT_FALSE(ShmSegmentExists(loan_segment));  // its last holder (the child) reclaimed it
        EXPECT_TRUE(ShmSegmentExists(heap_segment));   // pooled by the sender for the next copy
    }
    EXPECT_FALSE(ShmSegmentExists(heap_segment));  // the endpoint's pool went with it
    ::close(child.report);
    ::close(child.go);
}

TEST(ShmEndpoint, SegmentReclaimedWhenTheReceiverIsKilledHoldingTheBuffer) {
    const TempDir dir;
    const std::string address = "ipc://" + dir.path() + "/shm-kill";
    const std::string prefix = Prefix();
    Child child = StartReceiver(address, prefix);
    std::string segment;
    {
        zmq::context_t context;
        Endpoint push(context, IpcConfig(Role::kPush, address, true, prefix));
        SharedBuffer sealed;
        {
            WritableBuffer loan = push.Allocate(kLoanBytes);
            Fill(loan.bytes(), 1);
            sealed = loan.Seal();
        }
        segment = sealed.shm_segment()->name();
        ASSERT_EQ(push.Send(TestMessage(1, 1, {sealed})), SendStatus::kSent);
        const std::string line = ReadLine(child.report);
        EXPECT_NE(line.find(" same"), std::string::npos) << line;
        ASSERT_EQ(::kill(child.pid, SIGKILL), 0);  // dies holding the mapping
        EXPECT_EQ(WaitChild(child.pid), -SIGKILL);
        EXPECT_TRUE(ShmSegmentExists(segment));
    }  // the producer's buffer is released here: the dead holder does not keep the segment
    EXPECT_FALSE(ShmSegmentExists(segment));
    ::close(child.report);
    ::close(child.go);
}

/// A message whose one frame claims to be a descriptor with the given fields.
Message Forged(const std::string& name, std::uint64_t length, std::uint64_t declared,
               std::uint64_t generation = 1) {
    v1::ShmDescriptor descriptor;
    descriptor.set_segment_name(name);
    descriptor.set_byte_length(length);
    descriptor.set_generation(generation);
    const std::string bytes = descriptor.SerializeAsString();
    Message message = TestMessage(1);
    AppendFrame(message, SharedBuffer::Copy(bytes.data(), bytes.size()),
                v1::FRAME_KIND_SHM_DESCRIPTOR);
    message.envelope.mutable_frames(0)->set_payload_byte_length(declared);
    return message;
}

TEST(ShmEndpoint, ForgedOrMalformedDescriptorsAreDroppedAndCounted) {
    const TempDir dir;
    const std::string address = "ipc://" + dir.path() + "/shm-forged";
    const std::string prefix = Prefix();
    zmq::context_t context;
    Endpoint pull(context, IpcConfig(Role::kPull, address, true, prefix));
    Endpoint push(context, IpcConfig(Role::kPush, address, false, prefix));
    WritableBuffer real = push.Allocate(kLoanBytes);
    Fill(real.bytes(), 5);
    const SharedBuffer sealed = real.Seal();
    const ShmDescriptor lent = sealed.shm_segment()->Lend(sealed.size(), 1);
    const std::string missing = "/" + prefix + "-0-0-0000000000000000";
    const std::vector<Message> forged = {
        Forged("/etc/passwd", 10, 10),  // not of the family
        Forged(missing, 10, 10),        // no such segment
        Forged(lent.segment_name, kLoanBytes * 4, kLoanBytes * 4, lent.generation),  // too long
        Forged(lent.segment_name, kLoanBytes, kLoanBytes, lent.generation + 1),      // stale
        Forged(lent.segment_name, kLoanBytes, 10, lent.generation),  // length != declared
    };
    for (const auto& message : forged) ASSERT_EQ(push.Send(message), SendStatus::kSent);
    Message garbage = TestMessage(2);
    AppendFrame(garbage, SharedBuffer::Copy("\xff\xff\xff", 3), v1::FRAME_KIND_SHM_DESCRIPTOR);
    ASSERT_EQ(push.Send(garbage), SendStatus::kSent);
    ASSERT_EQ(push.Send(TestMessage(3, 1, {sealed})), SendStatus::kSent);  // a valid one last

    const auto received = pull.Receive(kTimeout);
    ASSERT_TRUE(received.has_value());
    EXPECT_EQ(received->envelope.header().sequence(), 3u);
    ASSERT_EQ(received->frames.size(), 1u);
    const std::string mapping = MappingOf(received->frames[0].data());  // the reader's mapping
    EXPECT_EQ(mapping, "/dev/shm" + lent.segment_name + " r--s");
    EXPECT_TRUE(Matches(received->frames[0].span(), 5));
    EXPECT_EQ(pull.counters().dropped_shm, forged.size() + 1);
    EXPECT_EQ(pull.counters().received, 1u);
    sealed.shm_segment()->Unlend(1);  // the reference lent above by hand was never taken
}

TEST(ShmEndpoint, DescriptorsAreRefusedOnAnEdgeThatIsNotIpc) {
    const std::string prefix = Prefix();
    zmq::context_t context;
    const std::string address = "inproc://shm-not-ipc-" + prefix;
    Endpoint pull(context, IpcConfig(Role::kPull, address, true, prefix));
    Endpoint push(context, IpcConfig(Role::kPush, address, false, prefix));
    auto segment = WritableBuffer::Shm(kSmallBytes, pull.config().shm);
    ASSERT_TRUE(segment.ok()) << segment.detail;
    const SharedBuffer sealed = segment.value->Seal();
    const ShmDescriptor lent = sealed.shm_segment()->Lend(sealed.size(), 1);
    ASSERT_EQ(push.Send(Forged(lent.segment_name, kSmallBytes, kSmallBytes, lent.generation)),
              SendStatus::kSent);
    ASSERT_EQ(push.Send(TestMessage(2, 1, {sealed})), SendStatus::kSent);  // inproc: a handle
    const auto received = pull.Receive(kTimeout);
    ASSERT_TRUE(received.has_value());
    EXPECT_EQ(received->envelope.header().sequence(), 2u);
    EXPECT_EQ(received->frames.at(0).data(), sealed.data());  // inproc: the very same bytes
    EXPECT_EQ(pull.counters().dropped_shm, 1u);
    EXPECT_EQ(push.counters().shm_lent, 0u);
    sealed.shm_segment()->Unlend(1);  // the reference lent above by hand was never taken
}

TEST(ShmEndpoint, PublisherLendsOneReferencePerSubscriberAndTheLastReleaseReclaims) {
    const TempDir dir;
    const std::string address = "ipc://" + dir.path() + "/shm-pub";
    const std::string prefix = Prefix();
    zmq::context_t context;
    Endpoint pub(context, IpcConfig(Role::kPublisher, address, true, prefix));
    Endpoint first(context, IpcConfig(Role::kSubscriber, address, false, prefix));
    Endpoint second(context, IpcConfig(Role::kSubscriber, address, false, prefix));
    ASSERT_TRUE(pub.WaitForSubscribers(2, kTimeout));
    ASSERT_TRUE(first.WaitReady(kTimeout));
    ASSERT_TRUE(second.WaitReady(kTimeout));
    std::string name;
    std::optional<Message> a, b;
    {
        WritableBuffer buffer = pub.Allocate(kLoanBytes);
        Fill(buffer.bytes(), 4);
        const SharedBuffer sealed = buffer.Seal();
        name = sealed.shm_segment()->name();
        ASSERT_EQ(pub.Send(TestMessage(1, 1, {sealed})), SendStatus::kSent);
        a = first.Receive(kTimeout);
        b = second.Receive(kTimeout);
    }  // the producer let go
    ASSERT_TRUE(a && b);
    EXPECT_TRUE(Matches(a->frames.at(0).span(), 4));
    EXPECT_TRUE(Matches(b->frames.at(0).span(), 4));
    EXPECT_EQ(MappingOf(a->frames[0].data()), "/dev/shm" + name + " r--s");  // no copy
    EXPECT_EQ(MappingOf(b->frames[0].data()), "/dev/shm" + name + " r--s");
    a.reset();
    EXPECT_TRUE(ShmSegmentExists(name));  // the second subscriber still holds it
    b.reset();
    EXPECT_FALSE(ShmSegmentExists(name));
}

// A message for one robot's topic has readers nobody counts (any subscriber of that topic): its
// frames go inline, so no reference is lent that no reader would release.
TEST(ShmEndpoint, PublisherSendsAMessageForOneRobotInlineAndLendsNothing) {
    const TempDir dir;
    const std::string address = "ipc://" + dir.path() + "/shm-robot";
    const std::string prefix = Prefix();
    zmq::context_t context;
    Endpoint pub(context, IpcConfig(Role::kPublisher, address, true, prefix));
    EndpointConfig config = IpcConfig(Role::kSubscriber, address, false, prefix);
    config.robot_id = 2;
    Endpoint sub(context, config);
    ASSERT_TRUE(pub.WaitForSubscribers(1, kTimeout));
    ASSERT_TRUE(sub.WaitReady(kTimeout));
    WritableBuffer buffer = pub.Allocate(kLoanBytes);
    Fill(buffer.bytes(), 6);
    const SharedBuffer sealed = buffer.Seal();
    ASSERT_NE(sealed.shm_segment(), nullptr);  // a frame that Send would have lent
    ASSERT_EQ(pub.SendToRobot(2, TestMessage(1, 1, {sealed})), SendStatus::kSent);
    const auto message = sub.Receive(kTimeout);
    ASSERT_TRUE(message.has_value());
    EXPECT_TRUE(Matches(message->frames.at(0).span(), 6));
    EXPECT_EQ(MappingOf(message->frames[0].data()).rfind("/dev/shm", 0), std::string::npos);
    EXPECT_EQ(pub.counters().shm_lent, 0u);
    EXPECT_EQ(sub.counters().shm_received, 0u);
}

TEST(ShmEndpoint, ConfigRejectsAZeroThresholdAndTooLargeAPool) {
    EndpointConfig config = Config(Role::kPush, "ipc:///tmp/x", true);
    config.shm_threshold_bytes = 0;
    try {
        config.Validate();
        FAIL() << "a zero threshold was accepted";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("shm_threshold_bytes"), std::string::npos);
    }
    config.shm_threshold_bytes = 1;
    config.shm_pool_segments = 100000;
    EXPECT_THROW(config.Validate(), std::invalid_argument);
    config.shm_pool_segments = 4;
    config.shm.prefix = "bad-prefix";
    EXPECT_THROW(config.Validate(), std::invalid_argument);
    EXPECT_TRUE(Config(Role::kPush, "ipc:///tmp/x", true).UsesShm());
    EXPECT_FALSE(Config(Role::kPush, "tcp://127.0.0.1:5", true).UsesShm());
}

}  // namespace
}  // namespace certislam::transport
