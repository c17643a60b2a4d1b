// Live LIO-SAM ingest: the bag source's pairing (nearest odometry within the gap), frames,
// selection, the bounded queue dropping its oldest keyframe, silence ending the stream.
#include "actors/ros/live_keyframes.h"

#include <gtest/gtest.h>

#include <thread>

namespace certislam::actors {
namespace {

constexpr std::int64_t kMs = 1'000'000;

Eigen::Isometry3d At(double x) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation().x() = x;
    return T;
}

slam::PointCloud OnePoint(float x) { return {Eigen::Vector3f(x, 0.f, 0.f)}; }

LiveIngestConfig NoSelection() {
    LiveIngestConfig c;
    c.select_keyframes = false;
    return c;
}

TEST(LiveKeyframesTest, PairsEachCloudWithTheNearestOdometryWithinTheGap) {
    LiveKeyframes live(NoSelection());
    live.OnOdometry(1000 * kMs, "odom", At(1.0));
    live.OnOdometry(1100 * kMs, "odom", At(2.0));
    live.OnCloud(1096 * kMs, "base_link", OnePoint(1.f));  // 4 ms from the second: paired
    live.OnCloud(1050 * kMs, "base_link", OnePoint(2.f));  // 50 ms from both: unpaired
    live.OnOdometry(1200 * kMs, "odom", At(3.0));
    live.OnCloud(1205 * kMs, "base_link", OnePoint(3.f));  // waits for a later odometry
    EXPECT_EQ(live.Stats().selected, 1);
    live.Close();  // pairs it with what there is (1200, 5 ms away)
    const KeyframeSource source = live.Source();
    auto a = source();
    auto b = source();
    ASSERT_TRUE(a && b);
    EXPECT_EQ(a->index, 0);
    EXPECT_EQ(b->index, 1);
    EXPECT_EQ(a->stamp_ns, 1096 * kMs);
    EXPECT_DOUBLE_EQ(a->T_odom_sensor.translation().x(), 2.0);
    EXPECT_DOUBLE_EQ(b->T_odom_sensor.translation().x(), 3.0);
    EXPECT_FALSE(source());
    const LiveIngestStats s = live.Stats();
    EXPECT_EQ(s.unpaired, 1);
    EXPECT_EQ(s.selected, 2);
    EXPECT_EQ(s.handed_out, 2);
    EXPECT_TRUE(s.ended);
}

TEST(LiveKeyframesTest, CloudsInTheOdometryFrameAreMappedIntoTheSensorFrame) {
    LiveKeyframes live(NoSelection());
    live.OnOdometry(10 * kMs, "odom", At(5.0));
    live.OnCloud(10 * kMs, "odom", OnePoint(6.f));       // registered cloud: odom frame
    live.OnCloud(10 * kMs, "base_link", OnePoint(6.f));  // deskewed cloud: sensor frame
    live.Close();
    const KeyframeSource source = live.Source();
    EXPECT_FLOAT_EQ((*source()->cloud)[0].x(), 1.f);
    EXPECT_FLOAT_EQ((*source()->cloud)[0].x(), 6.f);
}

TEST(LiveKeyframesTest, SelectsKeyframesByDistanceAsTheBagSource) {
    LiveIngestConfig config;
    config.selection.min_translation_m = 1.0;
    LiveKeyframes live(config);
    const std::vector<double> xs = {0.0, 0.4, 0.9, 1.1, 1.5, 2.3};
    std::vector<Eigen::Isometry3d> poses;
    for (size_t i = 0; i < xs.size(); ++i) {
        const std::int64_t t = static_cast<std::int64_t>(i + 1) * 100 * kMs;
        live.OnOdometry(t, "odom", At(xs[i]));
        live.OnCloud(t, "base_link", OnePoint(0.f));
        poses.push_back(At(xs[i]));
    }
    live.Close();
    const std::vector<int> expected = slam::SelectKeyframes(poses, config.selection);
    const KeyframeSource source = live.Source();
    std::vector<double> got;
    while (auto kf = source()) got.push_back(kf->T_odom_sensor.translation().x());
    ASSERT_EQ(got.size(), expected.size());
    for (size_t k = 0; k < got.size(); ++k) EXPECT_DOUBLE_EQ(got[k], xs[size_t(expected[k])]);
}

TEST(LiveKeyframesTest, AFullQueueDropsItsOldestKeyframeAndCountsIt) {
    LiveIngestConfig config = NoSelection();
    config.queue_capacity = 3;
    LiveKeyframes live(config);
    for (int i = 0; i < 5; ++i) {
        live.OnOdometry((i + 1) * 100 * kMs, "odom", At(i));
        live.OnCloud((i + 1) * 100 * kMs, "base_link", OnePoint(0.f));
    }
    EXPECT_EQ(live.Stats().dropped, 2);
    EXPECT_EQ(live.Stats().queued, 3);
    live.Close();
    const KeyframeSource source = live.Source();
    for (int i = 2; i < 5; ++i) {
        auto kf = source();
        ASSERT_TRUE(kf);
        EXPECT_EQ(kf->index, i - 2);  // indices stay consecutive across the drop
        EXPECT_DOUBLE_EQ(kf->T_odom_sensor.translation().x(), i);
    }
    EXPECT_FALSE(source());
    EXPECT_EQ(live.HandedOut().size(), 3u);
}

TEST(LiveKeyframesTest, SilenceEndsTheStreamOnlyWhenConfigured) {
    LiveIngestConfig config = NoSelection();
    config.end_after_silence_s = 0.2;
    LiveKeyframes live(config);
    live.OnOdometry(100 * kMs, "odom", At(0));
    live.OnCloud(100 * kMs, "base_link", OnePoint(0.f));
    const KeyframeSource source = live.Source();
    ASSERT_TRUE(source());
    const auto start = std::chrono::steady_clock::now();
    EXPECT_FALSE(source());  // blocks until LIO-SAM has been silent for 0.2 s
    EXPECT_GE(std::chrono::steady_clock::now() - start, std::chrono::milliseconds(100));
    EXPECT_TRUE(live.Stats().ended);
    live.OnCloud(200 * kMs, "base_link", OnePoint(0.f));  // after the end: ignored
    EXPECT_EQ(live.Stats().clouds, 1);
}

TEST(LiveKeyframesTest, RejectsABadConfigurationNamingTheField) {
    LiveIngestConfig config;
    config.queue_capacity = 0;
    try {
        LiveKeyframes live(config);
        FAIL() << "accepted queue_capacity 0";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("queue_capacity"), std::string::npos);
    }
}

}  // namespace
}  // namespace certislam::actors
