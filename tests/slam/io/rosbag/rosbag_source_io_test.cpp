// The ROS 1 bag keyframe source: bags written with ROS 1's own bag library (by hand, with odd
// cloud layouts, and through WriteRosbagKeyframes, including the real KAIST03 keyframes) read
// back and compared; truncated, corrupt and mislabelled bags give errors naming the file.
#include "slam/io/rosbag/rosbag_source_io.h"

#include <gtest/gtest.h>
#include <nav_msgs/Odometry.h>
#include <rosbag/bag.h>
#include <sensor_msgs/PointCloud2.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>

#include "slam/io/keyframe_sources_io.h"
#include "tests/data_paths.h"
#include "tests/scratch_dir.h"

namespace certislam::slam {
namespace {

namespace fs = std::filesystem;
using Status = KeyframeSourceResult::Status;
constexpr double kPoseTol = 1e-9;  // poses travel as float64: exact up to rounding
// KAIST03's rotations are printed to 6 digits, so not exactly orthonormal: the quaternion of
// the odometry message is their nearest rotation.
constexpr double kRoundedPoseTol = 1e-5;
constexpr float kOdomFrameTolM = 2e-4f;  // float32 round trip through the odom frame (< 1 km)
const std::string kKaist = test_data::DataPath("lidar/mulran_kaist03_keyframes");

fs::path Scratch(const std::string& name) {
    const fs::path dir = certislam::testing::ScratchDir();
    fs::create_directories(dir);
    fs::remove(dir / name);
    return dir / name;
}

// `n` keyframes along a curve with random clouds (fixed seed), stamps 0.5 s apart.
std::vector<Keyframe> MakeKeyframes(int n, int points) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> u(-30.f, 30.f);
    std::vector<Keyframe> kfs;
    for (int k = 0; k < n; ++k) {
        Keyframe kf;
        kf.index = k;
        kf.stamp_ns = 1'600'000'000'000'000'000LL + k * 500'000'000LL;
        kf.T_odom_sensor.linear() =
            Eigen::AngleAxisd(0.3 * k, Eigen::Vector3d(0.1, 0.2, 1.0).normalized()).matrix();
        kf.T_odom_sensor.translation() = Eigen::Vector3d(2.0 * k, 0.5 * k * k, 0.1 * k);
        PointCloud cloud;
        for (int i = 0; i < points; ++i) cloud.emplace_back(u(rng), u(rng), u(rng) / 10.f);
        kf.cloud = std::make_shared<const PointCloud>(std::move(cloud));
        kfs.push_back(std::move(kf));
    }
    return kfs;
}

void ExpectSamePose(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, double tol = kPoseTol) {
    EXPECT_TRUE(a.matrix().isApprox(b.matrix(), tol)) << a.matrix() << "\n vs \n" << b.matrix();
}

TEST(RosbagSource, WrittenKeyframesReadBackExactly) {
    const std::vector<Keyframe> kfs = MakeKeyframes(6, 500);
    const fs::path bag = Scratch("round_trip.bag");
    std::string error;
    ASSERT_TRUE(WriteRosbagKeyframes(bag, kfs, {}, &error)) << error;
    KeyframeSourceOptions options;
    options.robot = 3;
    const auto r = ReadRosbagKeyframes(bag, {}, options);
    ASSERT_TRUE(r.ok()) << r.error;
    ASSERT_EQ(r.keyframes.size(), kfs.size());
    for (size_t k = 0; k < kfs.size(); ++k) {
        EXPECT_EQ(r.keyframes[k].robot, 3);
        EXPECT_EQ(r.keyframes[k].index, static_cast<int>(k));
        EXPECT_EQ(r.keyframes[k].stamp_ns, kfs[k].stamp_ns);
        EXPECT_EQ(r.source_indices[k], static_cast<int>(k));
        ExpectSamePose(r.keyframes[k].T_odom_sensor, kfs[k].T_odom_sensor);
        ASSERT_TRUE(r.keyframes[k].cloud);
        EXPECT_EQ(*r.keyframes[k].cloud, *kfs[k].cloud);  // sensor frame: bit-exact
    }
}

TEST(RosbagSource, SelectionLimitAndPosesOnly) {
    const std::vector<Keyframe> kfs = MakeKeyframes(8, 10);
    const fs::path bag = Scratch("select.bag");
    std::string error;
    ASSERT_TRUE(WriteRosbagKeyframes(bag, kfs, {}, &error)) << error;
    KeyframeSourceOptions options;
    options.load_clouds = false;
    options.select_keyframes = true;
    options.selection.min_translation_m = 5.0;  // steps grow 2.1, 2.5, 3.2, 4.0, 4.9, 5.8 m
    options.selection.min_rotation_rad = 10.0;
    auto r = ReadRosbagKeyframes(bag, {}, options);
    ASSERT_TRUE(r.ok()) << r.error;
    EXPECT_EQ(r.source_indices, (std::vector<int>{0, 3, 5, 6, 7}));
    EXPECT_FALSE(r.keyframes[1].cloud);
    options.max_keyframes = 2;
    r = ReadRosbagKeyframes(bag, {}, options);
    ASSERT_TRUE(r.ok()) << r.error;
    EXPECT_EQ(r.source_indices, (std::vector<int>{0, 3}));
}

TEST(RosbagSource, KaistKeyframesInOdomFrameComeBackInSensorFrame) {
    KeyframeSourceOptions options;
    options.max_keyframes = 5;
    const auto folder = ReadScLioSamFolder(kKaist, options);
    ASSERT_TRUE(folder.ok()) << folder.error;
    RosbagSourceConfig config;
    config.cloud_frame = RosbagCloudFrame::kOdom;  // as LIO-SAM's cloud_registered_raw
    const fs::path bag = Scratch("kaist_odom_frame.bag");
    std::string error;
    ASSERT_TRUE(WriteRosbagKeyframes(bag, folder.keyframes, config, &error)) << error;
    const auto r = ReadRosbagKeyframes(bag);  // kAuto: frame_id "odom" = odometry frame
    ASSERT_TRUE(r.ok()) << r.error;
    ASSERT_EQ(r.keyframes.size(), folder.keyframes.size());
    for (size_t k = 0; k < r.keyframes.size(); ++k) {
        ExpectSamePose(r.keyframes[k].T_odom_sensor, folder.keyframes[k].T_odom_sensor,
                       kRoundedPoseTol);
        const PointCloud& a = *r.keyframes[k].cloud;
        const PointCloud& b = *folder.keyframes[k].cloud;
        ASSERT_EQ(a.size(), b.size());
        float worst = 0.f;
        for (size_t i = 0; i < a.size(); ++i) worst = std::max(worst, (a[i] - b[i]).norm());
        EXPECT_LT(worst, kOdomFrameTolM) << "keyframe " << k;
    }
}

// A LIO-SAM-like point (intensity first, a ring after z, padding), organised 2 x 3.
sensor_msgs::PointCloud2 OddLayoutCloud(std::int64_t stamp_ns, const PointCloud& points) {
    sensor_msgs::PointCloud2 msg;
    msg.header.stamp.fromNSec(stamp_ns);
    msg.header.frame_id = "lidar_link";
    const std::pair<const char*, std::uint32_t> fields[] = {
        {"intensity", 0}, {"x", 4}, {"y", 8}, {"z", 12}};
    for (const auto& [name, offset] : fields) {
        sensor_msgs::PointField f;
        f.name = name;
        f.offset = offset;
        f.datatype = sensor_msgs::PointField::FLOAT32;
        f.count = 1;
        msg.fields.push_back(f);
    }
    sensor_msgs::PointField ring;
    ring.name = "ring";
    ring.offset = 16;
    ring.datatype = sensor_msgs::PointField::UINT16;
    ring.count = 1;
    msg.fields.push_back(ring);
    msg.height = 2;
    msg.width = 3;
    msg.point_step = 24;
    msg.row_step = 3 * 24 + 8;  // row padding
    msg.data.assign(2 * msg.row_step, 0xAB);
    for (size_t i = 0; i < points.size(); ++i) {
        std::uint8_t* p = msg.data.data() + (i / 3) * msg.row_step + (i % 3) * msg.point_step;
        std::memcpy(p + 4, points[i].data(), 12);
    }
    return msg;
}

nav_msgs::Odometry Odometry(std::int64_t stamp_ns, double x) {
    nav_msgs::Odometry odom;
    odom.header.stamp.fromNSec(stamp_ns);
    odom.header.frame_id = "odom";
    odom.child_frame_id = "odom_mapping";
    odom.pose.pose.position.x = x;
    odom.pose.pose.orientation.w = 1.0;
    return odom;
}

ros::Time At(std::int64_t stamp_ns) {
    ros::Time t;
    t.fromNSec(stamp_ns);
    return t;
}

TEST(RosbagSource, OddLayoutPairsNearestOdometryAndDropsNaN) {
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const PointCloud points = {{1, 2, 3}, {4, 5, 6},    {nan, 0, 0},
                               {7, 8, 9}, {-1, -2, -3}, {0, 0, 1}};
    const fs::path path = Scratch("odd_layout.bag");
    const std::int64_t t0 = 1'000'000'000'000LL;
    {
        rosbag::Bag bag(path, rosbag::bagmode::Write);
        bag.write("/odom", At(t0 - 4'000'000), Odometry(t0 - 4'000'000, 1.0));  // 4 ms early
        bag.write("/odom", At(t0 + 3'000'000), Odometry(t0 + 3'000'000, 2.0));  // 3 ms late
        bag.write("/cloud", At(t0), OddLayoutCloud(t0, points));
        bag.write("/cloud", At(t0 + 500'000'000), OddLayoutCloud(t0 + 500'000'000, points));
    }
    RosbagSourceConfig config;
    config.cloud_topic = "/cloud";
    config.odometry_topic = "/odom";
    const auto r = ReadRosbagKeyframes(path, config);
    ASSERT_TRUE(r.ok()) << r.error;
    ASSERT_EQ(r.keyframes.size(), 1u);  // the second cloud has no odometry within 10 ms
    EXPECT_DOUBLE_EQ(r.keyframes[0].T_odom_sensor.translation().x(), 2.0);  // nearest: 3 ms
    const PointCloud expected = {{1, 2, 3}, {4, 5, 6}, {7, 8, 9}, {-1, -2, -3}, {0, 0, 1}};
    EXPECT_EQ(*r.keyframes[0].cloud, expected);  // "lidar_link" != "odom": sensor frame
}

TEST(RosbagSource, BigEndianAndFloat64CloudsAreRejectedWithTheReason) {
    const PointCloud points(6, Eigen::Vector3f(1, 2, 3));
    const std::int64_t t0 = 2'000'000'000LL;
    for (const bool big_endian : {true, false}) {
        sensor_msgs::PointCloud2 cloud = OddLayoutCloud(t0, points);
        if (big_endian) {
            cloud.is_bigendian = true;
        } else {
            cloud.fields[2].datatype = sensor_msgs::PointField::FLOAT64;  // y
        }
        const fs::path path = Scratch("bad_cloud.bag");
        {
            rosbag::Bag bag(path, rosbag::bagmode::Write);
            bag.write("/odom", At(t0), Odometry(t0, 0.0));
            bag.write("/cloud", At(t0), cloud);
        }
        RosbagSourceConfig config;
        config.cloud_topic = "/cloud";
        config.odometry_topic = "/odom";
        const auto r = ReadRosbagKeyframes(path, config);
        EXPECT_EQ(r.status, Status::kBadScan);
        EXPECT_NE(r.error.find(path.string()), std::string::npos) << r.error;
        EXPECT_NE(r.error.find(big_endian ? "is_bigendian" : "field 'y' is FLOAT64"),
                  std::string::npos)
            << r.error;
    }
}

TEST(RosbagSource, MissingOrMistypedTopicIsNamed) {
    const fs::path bag = Scratch("topics.bag");
    std::string error;
    ASSERT_TRUE(WriteRosbagKeyframes(bag, MakeKeyframes(2, 5), {}, &error)) << error;
    RosbagSourceConfig config;
    config.cloud_topic = "/nope";
    auto r = ReadRosbagKeyframes(bag, config);
    EXPECT_EQ(r.status, Status::kMissingTopic);
    EXPECT_NE(r.error.find("no topic '/nope'"), std::string::npos) << r.error;
    EXPECT_NE(r.error.find("/lio_sam/mapping/odometry [nav_msgs/Odometry]"), std::string::npos)
        << r.error;
    config.cloud_topic = RosbagSourceConfig{}.odometry_topic;
    r = ReadRosbagKeyframes(bag, config);
    EXPECT_EQ(r.status, Status::kMissingTopic);
    EXPECT_NE(r.error.find("is nav_msgs/Odometry, expected sensor_msgs/PointCloud2"),
              std::string::npos)
        << r.error;
}

TEST(RosbagSource, TruncatedCorruptOrMissingBagGivesACleanError) {
    const fs::path bag = Scratch("whole.bag");
    std::string error;
    ASSERT_TRUE(WriteRosbagKeyframes(bag, MakeKeyframes(6, 2000), {}, &error)) << error;
    std::ifstream in(bag, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), {});
    for (const double fraction : {0.02, 0.3, 0.6, 0.97}) {
        const fs::path cut = Scratch("truncated.bag");
        std::ofstream(cut, std::ios::binary)
            .write(bytes.data(), static_cast<std::streamsize>(bytes.size() * fraction));
        const auto r = ReadRosbagKeyframes(cut);
        EXPECT_EQ(r.status, Status::kBadBag) << "fraction " << fraction << ": " << r.error;
        EXPECT_EQ(r.error.rfind(cut.string() + ": ", 0), 0u) << r.error;
    }
    const fs::path junk = Scratch("junk.bag");
    std::ofstream(junk) << "#ROSBAG V2.0\nthis is not a bag\n";
    EXPECT_EQ(ReadRosbagKeyframes(junk).status, Status::kBadBag);
    EXPECT_EQ(ReadRosbagKeyframes(Scratch("absent.bag")).status, Status::kCannotOpen);
}

TEST(RosbagSource, ConfigValidationNamesTheField) {
    RosbagSourceConfig config;
    config.max_stamp_gap_s = -1.0;
    try {
        config.Validate();
        FAIL() << "expected std::invalid_argument";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("max_stamp_gap_s"), std::string::npos);
    }
    config = {};
    config.odometry_topic.clear();
    EXPECT_THROW(config.Validate(), std::invalid_argument);
}

}  // namespace
}  // namespace certislam::slam
