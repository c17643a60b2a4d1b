// Durable per-robot log: messages come back intact after a restart, a torn last record is
// ignored, and a restarted ingest actor publishes its logged keyframes again before new ones.
#include "actors/durable_log.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
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
