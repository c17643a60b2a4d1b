// Durable per-robot log: messages come back intact after a restart, a torn last record is
// cut off, a log of another mission or a corrupt one is refused or moved aside, and a restarted
// ingest actor publishes its logged keyframes again before new ones.
#include "actors/durable_log.h"

#include <gtest/gtest.h>
#include <sys/resource.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <thread>

#include "actors/convert.h"
#include "actors/ingest_actor.h"

namespace certislam::actors {
namespace {

std::string TempPath(const std::string& name) {
    return (std::filesystem::temp_directory_path() /
            ("certislam_log_" + std::to_string(getpid()) + "_" + name))
        .string();
}

slam::Keyframe MakeKeyframe(int index) {
    slam::Keyframe kf;
    kf.robot = 1;
    kf.index = index;
    kf.stamp_ns = 1000 + index;
    kf.T_odom_sensor.translation() = Eigen::Vector3d(index, 0, 0);
    kf.cloud = std::make_shared<slam::PointCloud>(200 + index, Eigen::Vector3f(index, 2, 3));
    return kf;
}

TEST(DurableLog, MessagesSurviveAndATornTailIsIgnored) {
    const std::string path = TempPath("torn");
    std::filesystem::remove(path);
    {
        DurableLog log(path);
        for (int i = 0; i < 3; ++i) log.Append(EncodeKeyframe(MakeKeyframe(i), i));
        EXPECT_EQ(log.appended(), 3);
    }
    {
        std::ofstream tail(path, std::ios::binary | std::ios::app);
        const std::uint32_t frames = 2;
        tail.write(reinterpret_cast<const char*>(&frames), sizeof(frames));
        tail.write("\x10\x00\x00", 3);  // a crash in the middle of the next record
    }
    const DurableLogRead read = ReadDurableLog(path);
    EXPECT_TRUE(read.torn_tail);
    ASSERT_EQ(read.messages.size(), 3u);
    for (int i = 0; i < 3; ++i) {
        const auto kf = DecodeKeyframe(read.messages[i]);
        ASSERT_TRUE(kf.has_value());
        EXPECT_EQ(kf->index, i);
        EXPECT_EQ(kf->cloud->size(), 200u + i);
        EXPECT_EQ((*kf->cloud)[0], Eigen::Vector3f(i, 2, 3));
    }
    EXPECT_TRUE(ReadDurableLog(TempPath("missing")).messages.empty());
    std::filesystem::remove(path);
}

void AppendKeyframes(const std::string& path, const std::string& identity, int first, int last) {
    DurableLog log(path, identity);
    for (int i = first; i <= last; ++i) log.Append(EncodeKeyframe(MakeKeyframe(i), i));
}

std::string RefusalOf(const std::string& path, const std::string& identity) {
    try {
        PrepareDurableLog(path, identity, StaleLogPolicy::kRefuse);
    } catch (const std::runtime_error& e) {
        return e.what();
    }
    return "";
}

TEST(DurableLog, ATornTailIsCutOffSoLaterAppendsAreReadBack) {
    const std::string path = TempPath("torn_then_append");
    std::filesystem::remove(path);
    AppendKeyframes(path, "seed: 1\n", 0, 1);
    std::ofstream(path, std::ios::binary | std::ios::app).write("\x02\x00", 2);  // crash
    const DurableLogCheck check = PrepareDurableLog(path, "seed: 1\n", StaleLogPolicy::kRefuse);
    EXPECT_TRUE(check.truncated_tail);
    EXPECT_EQ(check.records, 2);
    AppendKeyframes(path, "seed: 1\n", 2, 3);
    const DurableLogRead read = ReadDurableLog(path);
    EXPECT_FALSE(read.torn_tail);
    ASSERT_EQ(read.messages.size(), 4u);
    EXPECT_EQ(DecodeKeyframe(read.messages[3])->index, 3);
    EXPECT_EQ(read.identity, "seed: 1\n");
    std::filesystem::remove(path);
}

// A record claiming a 3 GiB frame (below the per-frame cap) in a file of a few kilobytes is a torn
// tail, found without allocating the claim: the read runs under an address-space limit of 1 GiB
// more than the process maps, where allocating the claim throws std::bad_alloc.
TEST(DurableLog, AFrameLongerThanTheFileIsATornTailNotAnAllocation) {
    const std::string path = TempPath("forged_size");
    std::filesystem::remove(path);
    AppendKeyframes(path, "seed: 1\n", 0, 1);
    const auto good_bytes = std::filesystem::file_size(path);
    const std::uint32_t count = 1;
    const std::uint64_t claimed = 3ull << 30;
    std::ofstream out(path, std::ios::binary | std::ios::app);
    out.write(reinterpret_cast<const char*>(&count), sizeof count);
    out.write(reinterpret_cast<const char*>(&claimed), sizeof claimed);
    out.write("forged", 6);
    out.close();
    long pages = 0;
    std::ifstream("/proc/self/statm") >> pages;
    rlimit old{};
    ASSERT_EQ(getrlimit(RLIMIT_AS, &old), 0);
    rlimit limit = old;
    limit.rlim_cur = static_cast<rlim_t>(pages) * sysconf(_SC_PAGESIZE) + (1ull << 30);
    ASSERT_EQ(setrlimit(RLIMIT_AS, &limit), 0);
    DurableLogRead read;
    EXPECT_NO_THROW(read = ReadDurableLog(path));
    ASSERT_EQ(setrlimit(RLIMIT_AS, &old), 0);
    EXPECT_TRUE(read.torn_tail);
    EXPECT_EQ(read.messages.size(), 2u);
    EXPECT_EQ(read.good_bytes, good_bytes);
    std::filesystem::remove(path);
}

TEST(DurableLog, AnotherMissionsLogIsRefusedNamingTheDifference) {
    const std::string path = TempPath("other_mission");
    std::filesystem::remove(path);
    AppendKeyframes(path, "robot: 1\nsource.seed: 1\n", 0, 2);
    const std::string refusal = RefusalOf(path, "robot: 1\nsource.seed: 2\n");
    EXPECT_NE(refusal.find(path + ": written by another mission: 'source.seed: 1' in the log, "
                                  "'source.seed: 2' now"),
              std::string::npos)
        << refusal;
    EXPECT_EQ(ReadDurableLog(path).messages.size(), 3u);  // refused, not lost
    EXPECT_EQ(RefusalOf(path, "robot: 1\nsource.seed: 1\n"), "");
    std::filesystem::remove(path);
}

TEST(DurableLog, ALogWithoutHeaderOrWithACorruptRecordIsRefused) {
    const std::string path = TempPath("corrupt");
    std::ofstream(path, std::ios::binary) << "keyframes from an older release";
    EXPECT_NE(RefusalOf(path, "x").find("not a certislam durable log (no header)"),
              std::string::npos);
    std::filesystem::remove(path);
    AppendKeyframes(path, "x", 0, 0);
    const auto offset = std::filesystem::file_size(path);
    {
        std::ofstream out(path, std::ios::binary | std::ios::app);
        const std::uint32_t frames = 1;
        const std::uint64_t size = 5;
        out.write(reinterpret_cast<const char*>(&frames), sizeof(frames));
        out.write(reinterpret_cast<const char*>(&size), sizeof(size));
        out.write("junk!", 5);  // a complete record whose frame is no envelope
    }
    AppendKeyframes(path, "x", 1, 1);
    EXPECT_NE(RefusalOf(path, "x").find("1 corrupt record(s), the first at byte " +
                                        std::to_string(offset)),
              std::string::npos)
        << RefusalOf(path, "x");
    std::filesystem::remove(path);
}

TEST(DurableLog, AStaleLogIsMovedAsideOnRequestAndANewOneStarts) {
    const std::string path = TempPath("move_aside");
    std::filesystem::remove(path);
    std::filesystem::remove(path + ".stale-1");
    AppendKeyframes(path, "mission A", 0, 2);
    const DurableLogCheck check = PrepareDurableLog(path, "mission B", StaleLogPolicy::kMoveAside);
    EXPECT_EQ(check.moved_to, path + ".stale-1");
    EXPECT_FALSE(std::filesystem::exists(path));
    EXPECT_EQ(ReadDurableLog(path + ".stale-1").messages.size(), 3u);  // kept, not deleted
    AppendKeyframes(path, "mission B", 5, 5);
    EXPECT_EQ(ReadDurableLog(path).identity, "mission B");
    EXPECT_EQ(ReadDurableLog(path).messages.size(), 1u);
    std::filesystem::remove(path);
    std::filesystem::remove(path + ".stale-1");
}

/// Runs an ingest actor over `source` with a log and returns the indices a subscriber got.
std::vector<int> RunIngest(const std::string& log_path, int first, int last, int* replayed) {
    zmq::context_t context;
    const TeamWiring w = InprocWiring(1, {1});
    IngestConfig config;
    config.local_subscribers = 1;
    config.log_path = log_path;
    auto next = std::make_shared<int>(first);
    IngestActor ingest(
        context, w,
        [next, last]() -> std::optional<slam::Keyframe> {
            if (*next > last) return std::nullopt;
            return MakeKeyframe((*next)++);
        },
        config);
    transport::Endpoint listener(context, ClientConfig(w, Edge::kKeyframes, 1));
    ingest.Start();
    std::vector<int> got;
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
    while (!ingest.Finished() || listener.queued() > 0) {
        if (std::chrono::steady_clock::now() > deadline) break;
        if (auto m = listener.Receive(std::chrono::milliseconds(20))) {
            if (auto kf = DecodeKeyframe(*m)) got.push_back(kf->index);
        }
    }
    while (auto m = listener.Receive(std::chrono::milliseconds(50))) {
        if (auto kf = DecodeKeyframe(*m)) got.push_back(kf->index);
    }
    ingest.Stop();
    *replayed = ingest.Replayed();
    return got;
}

TEST(DurableLog, RestartedIngestRepublishesWhatItHadContributed) {
    const std::string path = TempPath("ingest");
    std::filesystem::remove(path);
    int replayed = -1;
    EXPECT_EQ(RunIngest(path, 0, 4, &replayed), (std::vector<int>{0, 1, 2, 3, 4}));
    EXPECT_EQ(replayed, 0);
    // After the restart the (live) sensor goes on at keyframe 5: 0..4 come from the log.
    EXPECT_EQ(RunIngest(path, 5, 7, &replayed), (std::vector<int>{0, 1, 2, 3, 4, 5, 6, 7}));
    EXPECT_EQ(replayed, 5);
    // A replayable source that starts over is not published twice.
    EXPECT_EQ(RunIngest(path, 0, 9, &replayed), (std::vector<int>{0, 1, 2, 3, 4, 5, 6, 7, 8, 9}));
    EXPECT_EQ(replayed, 8);
    std::filesystem::remove(path);
}

}  // namespace
}  // namespace certislam::actors
