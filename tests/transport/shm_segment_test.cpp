// Tests of the shared-memory buffers with real processes: exact bytes across fork(), read-only
// mappings, reclamation by the last holder and after SIGKILL, forged descriptors rejected.
#include "transport/shm_segment.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fcntl.h>
#include <algorithm>
#include <chrono>
#include <cstring>
#include <random>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace certislam::transport {
namespace {

constexpr std::size_t kBufferBytes = (std::size_t{1} << 20) + 13;  ///< not a page multiple
constexpr unsigned kSeed = 7;

/// A prefix of this test process alone, so the reaper never touches anyone else's segments.
ShmConfig TestConfig() {
    ShmConfig config;
    config.prefix = "cstest" + std::to_string(::getpid());
    return config;
}

void FillPattern(std::span<std::byte> bytes) {
    std::mt19937 rng(kSeed);
    for (std::byte& b : bytes) b = static_cast<std::byte>(rng() & 0xff);
}

bool MatchesPattern(std::span<const std::byte> bytes) {
    std::vector<std::byte> expected(bytes.size());
    FillPattern(expected);
    return std::equal(bytes.begin(), bytes.end(), expected.begin());
}

ShmSegment MakePublished(const ShmConfig& config, ShmDescriptor* descriptor, int readers = 1) {
    auto created = ShmSegment::Create(kBufferBytes, config);
    EXPECT_TRUE(created.ok()) << created.detail;
    ShmSegment segment = std::move(*created.value);
    FillPattern(segment.writable());
    *descriptor = segment.Publish(kBufferBytes, readers);
    return segment;
}

/// Exit status of a child (-signal when it was killed by one).
int WaitChild(pid_t pid) {
    int status = 0;
    EXPECT_EQ(::waitpid(pid, &status, 0), pid);
    if (WIFSIGNALED(status)) return -WTERMSIG(status);
    return WEXITSTATUS(status);
}

/// A child that opens the descriptor, reports on `ready` and then blocks until killed.
pid_t SpawnHolder(const ShmConfig& config, const ShmDescriptor& descriptor) {
    int ready[2];
    EXPECT_EQ(::pipe(ready), 0);
    const pid_t pid = ::fork();
    if (pid == 0) {
        ::close(ready[0]);
        ShmReader reader(config);
        auto view = reader.Open(descriptor);
        const char status = view.ok() && MatchesPattern(view.value->bytes()) ? 'y' : 'n';
        if (::write(ready[1], &status, 1) != 1) ::_exit(3);
        for (;;) ::pause();
    }
    ::close(ready[1]);
    char status = 0;
    EXPECT_EQ(::read(ready[0], &status, 1), 1);
    ::close(ready[0]);
    EXPECT_EQ(status, 'y');
    return pid;
}

TEST(ShmSegment, ReaderInAnotherProcessSeesTheExactBytes) {
    const ShmConfig config = TestConfig();
    ShmDescriptor descriptor;
    std::string name;
    {
        ShmSegment segment = MakePublished(config, &descriptor);
        name = segment.name();
        const pid_t pid = ::fork();
        if (pid == 0) {
            int code = 2;
            {
                ShmReader reader(config);
                auto view = reader.Open(descriptor);
                if (view.ok()) code = MatchesPattern(view.value->bytes()) ? 0 : 1;
            }  // released before exit
            ::_exit(code);
        }
        EXPECT_EQ(WaitChild(pid), 0);
        EXPECT_TRUE(ShmSegmentExists(name));  // the writer still holds it
    }
    EXPECT_FALSE(ShmSegmentExists(name));  // the last holder (the writer) released it
}

TEST(ShmSegment, ReaderMappingIsReadOnly) {
    const ShmConfig config = TestConfig();
    ShmDescriptor descriptor;
    ShmSegment segment = MakePublished(config, &descriptor);
    const pid_t pid = ::fork();
    if (pid == 0) {
        ShmReader reader(config);
        auto view = reader.Open(descriptor);
        if (!view.ok()) ::_exit(2);
        auto* bytes = const_cast<std::byte*>(view.value->bytes().data());
        bytes[0] = std::byte{0};  // must fault
        ::_exit(0);
    }
    EXPECT_EQ(WaitChild(pid), -SIGSEGV);
    EXPECT_TRUE(MatchesPattern(segment.writable().first(kBufferBytes)));
}

TEST(ShmSegment, ReclaimedWhenTheParentReleasesAfterAHolderWasKilled) {
    const ShmConfig config = TestConfig();
    ShmDescriptor descriptor;
    std::string name;
    {
        ShmSegment segment = MakePublished(config, &descriptor);
        name = segment.name();
        const pid_t pid = SpawnHolder(config, descriptor);
        ASSERT_EQ(::kill(pid, SIGKILL), 0);
        EXPECT_EQ(WaitChild(pid), -SIGKILL);
        EXPECT_TRUE(ShmSegmentExists(name));
    }
    EXPECT_FALSE(ShmSegmentExists(name));  // the dead holder did not keep it alive
}

TEST(ShmSegment, ReaperReclaimsASegmentWhoseLastHolderWasKilledEvenAsAZombie) {
    const ShmConfig config = TestConfig();
    ShmDescriptor descriptor;
    std::string name;
    pid_t pid = 0;
    {
        ShmSegment segment = MakePublished(config, &descriptor);
        name = segment.name();
        pid = SpawnHolder(config, descriptor);
    }
    EXPECT_TRUE(ShmSegmentExists(name));     // the child still holds it
    EXPECT_EQ(ReapShmSegments(config), 0u);  // and it is alive
    ASSERT_EQ(::kill(pid, SIGKILL), 0);
    siginfo_t info{};
    ASSERT_EQ(::waitid(P_PID, static_cast<id_t>(pid), &info, WEXITED | WNOWAIT), 0);  // zombie
    EXPECT_TRUE(ShmSegmentExists(name));
    EXPECT_EQ(ReapShmSegments(config), 1u);
    EXPECT_FALSE(ShmSegmentExists(name));
    EXPECT_EQ(WaitChild(pid), -SIGKILL);
}

TEST(ShmSegment, LastOfSeveralReadersReclaimsAndPendingReferencesKeepItAlive) {
    const ShmConfig config = TestConfig();
    ShmDescriptor descriptor;
    std::string name;
    {
        ShmSegment segment = MakePublished(config, &descriptor, /*readers=*/2);
        name = segment.name();
    }
    EXPECT_TRUE(ShmSegmentExists(name));  // writer gone, two references pending
    ShmReader reader(config);
    auto first = reader.Open(descriptor);
    auto second = reader.Open(descriptor);
    ASSERT_TRUE(first.ok()) << first.detail;
    ASSERT_TRUE(second.ok()) << second.detail;
    EXPECT_EQ(first.value->bytes().data(), second.value->bytes().data());  // one mapping
    first.value.reset();
    EXPECT_TRUE(ShmSegmentExists(name));
    second.value.reset();
    EXPECT_FALSE(ShmSegmentExists(name));
}

TEST(ShmSegment, ReusableOnlyWhenNoReaderHoldsItAndRepublishingMakesOldDescriptorsStale) {
    const ShmConfig config = TestConfig();
    ShmDescriptor first;
    ShmSegment segment = MakePublished(config, &first);
    EXPECT_FALSE(segment.Reusable());  // a reference is pending
    ShmReader reader(config);
    {
        auto view = reader.Open(first);
        ASSERT_TRUE(view.ok()) << view.detail;
        EXPECT_FALSE(segment.Reusable());  // a reader holds the bytes
    }
    EXPECT_TRUE(segment.Reusable());
    const ShmDescriptor second = segment.Publish(100, 1, 8);
    EXPECT_EQ(reader.Open(first).status, ShmStatus::kStaleGeneration);
    auto view = reader.Open(second);
    ASSERT_TRUE(view.ok()) << view.detail;
    EXPECT_EQ(view.value->bytes().size(), 100u);
    EXPECT_EQ(reader.cached(), 1u);  // the reused segment was not mapped again
}

TEST(ShmSegment, ForgedOrCorruptDescriptorsAreRejectedWithAStatus) {
    const ShmConfig config = TestConfig();
    ShmDescriptor good;
    ShmSegment segment = MakePublished(config, &good, /*readers=*/1);
    ShmReader reader(config);
    const std::string family = "/" + config.prefix + "-";
    for (const std::string& bad :
         {std::string(""), std::string("/etc/passwd"), family + "../../etc/passwd", family,
          std::string("/x-1"), family + std::string(300, 'a'), family + "a b"}) {
        ShmDescriptor d = good;
        d.segment_name = bad;
        EXPECT_EQ(reader.Open(d).status, ShmStatus::kBadName) << bad;
    }
    ShmDescriptor d = good;
    d.segment_name = family + "0-0-nothere";
    EXPECT_EQ(reader.Open(d).status, ShmStatus::kNotFound);

    d = good;
    d.generation = good.generation + 1;
    EXPECT_EQ(reader.Open(d).status, ShmStatus::kStaleGeneration);
    d = good;
    d.byte_length = good.byte_length + 1;
    EXPECT_EQ(reader.Open(d).status, ShmStatus::kOutOfRange);
    d = good;
    d.offset_bytes = ~std::uint64_t{0};
    EXPECT_EQ(reader.Open(d).status, ShmStatus::kOutOfRange);
    d = good;
    d.offset_bytes = 1;  // 1 + length wraps past the end
    EXPECT_EQ(reader.Open(d).status, ShmStatus::kOutOfRange);

    // Not a segment: an shm object of the family's name with garbage in it.
    const std::string fake = family + "fake";
    const int fd = ::shm_open(fake.c_str(), O_CREAT | O_RDWR, 0600);
    ASSERT_GE(fd, 0);
    std::vector<char> garbage(8192, 'x');
    ASSERT_EQ(::write(fd, garbage.data(), garbage.size()), static_cast<ssize_t>(garbage.size()));
    ::close(fd);
    d = good;
    d.segment_name = fake;
    EXPECT_EQ(reader.Open(d).status, ShmStatus::kBadSegment);
    ::shm_unlink(fake.c_str());

    auto view = reader.Open(good);  // the only reference
    ASSERT_TRUE(view.ok()) << view.detail;
    EXPECT_TRUE(MatchesPattern(view.value->bytes()));
    EXPECT_EQ(reader.Open(good).status, ShmStatus::kNoLoan);  // a replayed descriptor
}

TEST(ShmSegment, AReferenceNotTakenWithinTheTtlExpiresAndNoLongerHoldsTheSegment) {
    ShmConfig config = TestConfig();
    config.loan_ttl = std::chrono::milliseconds(1);
    ShmDescriptor descriptor;
    std::string name;
    {
        ShmSegment segment = MakePublished(config, &descriptor);
        name = segment.name();
        std::this_thread::sleep_for(std::chrono::milliseconds(20));  // let the loan expire
        ShmReader reader(config);
        EXPECT_EQ(reader.Open(descriptor).status, ShmStatus::kLoanExpired);
        EXPECT_TRUE(segment.Reusable());
    }
    EXPECT_FALSE(ShmSegmentExists(name));
}

TEST(ShmConfig, ValidateNamesTheField) {
    ShmConfig config;
    config.prefix = "bad/prefix";
    try {
        config.Validate();
        FAIL() << "accepted a bad prefix";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("ShmConfig.prefix"), std::string::npos);
    }
    config = ShmConfig{};
    config.loan_ttl = std::chrono::milliseconds(0);
    EXPECT_THROW(config.Validate(), std::invalid_argument);
}

TEST(ShmDescriptor, RoundTripsThroughProtobuf) {
    const ShmDescriptor d{"/certislam-1-2-abc", 4096, 12345, 77};
    v1::ShmDescriptor wire;
    ASSERT_TRUE(wire.ParseFromString(ToProto(d).SerializeAsString()));
    const ShmDescriptor back = FromProto(wire);
    EXPECT_EQ(back.segment_name, d.segment_name);
    EXPECT_EQ(back.offset_bytes, d.offset_bytes);
    EXPECT_EQ(back.byte_length, d.byte_length);
    EXPECT_EQ(back.generation, d.generation);
}

}  // namespace
}  // namespace certislam::transport
