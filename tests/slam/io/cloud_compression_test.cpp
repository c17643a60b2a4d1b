// The compact cloud compression: exact multiset of quantised points back, error within half a step,
// real clouds shrink, out-of-range points are counted, malformed bytes are refused, and the
// hdl_pair_fast_gicp registration still meets 5 cm / 1 degree on decoded clouds.
#include "slam/io/cloud_compression.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <random>

#include "slam/frontend/downsample.h"
#include "slam/frontend/registration.h"
#include "slam/io/cloud_io.h"
#include "tests/data_paths.h"

namespace certislam::slam {
namespace {

const std::string kLidar = test_data::DataPath("lidar/");
constexpr double kFloatSlackM = 1e-5;  // float32 rounding of coordinates up to ~100 m
constexpr double kHdlMaxTranslationM = 0.05;
constexpr double kHdlMaxRotationDeg = 1.0;
constexpr double kMinCompressionVs12Bytes = 3.0;  // 0.4 m-voxel real cloud, 1 cm steps

PointCloud Load(const std::string& relative) {
    CloudReadResult r = ReadCloud(kLidar + relative);
    EXPECT_TRUE(r.ok()) << r.error;
    return std::move(r.cloud);
}

bool Less(const Eigen::Vector3f& a, const Eigen::Vector3f& b) {
    return std::lexicographical_compare(a.data(), a.data() + 3, b.data(), b.data() + 3);
}

PointCloud RandomCloud(int n, std::uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> xy(-90.f, 90.f), z(-3.f, 15.f);
    PointCloud cloud;
    for (int i = 0; i < n; ++i) cloud.emplace_back(xy(rng), xy(rng), z(rng));
    return cloud;
}

TEST(CloudCompression, DecodesTheQuantisedPointsWithinHalfAStep) {
    for (const double resolution : {0.005, 0.01, 0.02}) {
        const PointCloud cloud = RandomCloud(20000, 3);
        CloudCompressionConfig config;
        config.resolution_m = resolution;
        const CloudEncodeResult encoded = EncodeCloud(cloud, config);
        EXPECT_EQ(encoded.points_dropped, 0);
        const CloudDecodeResult decoded = DecodeCloud(encoded.bytes);
        ASSERT_TRUE(decoded.ok()) << decoded.error;
        EXPECT_EQ(decoded.resolution_m, resolution);
        PointCloud expected;
        for (const auto& p : cloud) {
            Eigen::Vector3f q;
            for (int k = 0; k < 3; ++k) {
                const long steps = std::lround(static_cast<double>(p[k]) / resolution);
                q[k] = static_cast<float>(static_cast<double>(steps) * resolution);
                ASSERT_LE(std::abs(q[k] - p[k]), resolution / 2 + kFloatSlackM);
            }
            expected.push_back(q);
        }
        PointCloud got = decoded.cloud;
        std::sort(expected.begin(), expected.end(), Less);
        std::sort(got.begin(), got.end(), Less);
        EXPECT_EQ(got, expected) << "resolution " << resolution;
    }
}

TEST(CloudCompression, RealDownsampledCloudShrinksAtLeastThreeTimes) {
    const PointCloud cloud =
        VoxelDownsample(Load("mulran_kaist03_keyframes/Scans/000000.pcd"), 0.4);
    const CloudEncodeResult encoded = EncodeCloud(cloud);
    const double ratio = 12.0 * static_cast<double>(cloud.size()) / encoded.bytes.size();
    std::printf("KAIST03 keyframe 0 at 0.4 m: %zu points, %zu B float32 -> %zu B encoded (%.2fx)\n",
                cloud.size(), 12 * cloud.size(), encoded.bytes.size(), ratio);
    EXPECT_GE(ratio, kMinCompressionVs12Bytes);
    EXPECT_EQ(DecodeCloud(encoded.bytes).cloud.size(), cloud.size());
}

TEST(CloudCompression, OutOfRangeAndNonFinitePointsAreDroppedAndCounted) {
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const PointCloud cloud = {{1, 2, 3}, {400, 0, 0}, {nan, 0, 0}, {-327.6f, 0, 1}, {0, 0, -500}};
    const CloudEncodeResult encoded = EncodeCloud(cloud);  // 1 cm: +-327.67 m
    EXPECT_EQ(encoded.points_dropped, 3);
    const CloudDecodeResult decoded = DecodeCloud(encoded.bytes);
    ASSERT_TRUE(decoded.ok()) << decoded.error;
    EXPECT_EQ(decoded.cloud.size(), 2u);
    const CloudDecodeResult empty = DecodeCloud(EncodeCloud(PointCloud{}).bytes);
    ASSERT_TRUE(empty.ok()) << empty.error;
    EXPECT_TRUE(empty.cloud.empty());
}

TEST(CloudCompression, MalformedBytesAreRefused) {
    const std::vector<std::uint8_t> bytes = EncodeCloud(RandomCloud(500, 4)).bytes;
    for (const std::size_t keep :
         {std::size_t{0}, std::size_t{3}, std::size_t{16}, bytes.size() / 2, bytes.size() - 1}) {
        const std::vector<std::uint8_t> cut(bytes.begin(), bytes.begin() + keep);
        EXPECT_FALSE(DecodeCloud(cut).ok()) << "kept " << keep << " bytes";
    }
    std::vector<std::uint8_t> bad = bytes;
    bad[0] ^= 0xFF;  // magic
    EXPECT_FALSE(DecodeCloud(bad).ok());
    bad = bytes;
    bad[4] ^= 0x01;  // point count no longer matches the compressed size
    EXPECT_FALSE(DecodeCloud(bad).ok());
    bad = bytes;
    bad[7] = 0xFF;  // absurd point count
    EXPECT_FALSE(DecodeCloud(bad).ok());
    bad = bytes;
    const double negative = -0.01;
    std::memcpy(bad.data() + 8, &negative, 8);
    EXPECT_FALSE(DecodeCloud(bad).ok());
    EXPECT_THROW(EncodeCloud({}, CloudCompressionConfig{0.0, 9}), std::invalid_argument);
    EXPECT_THROW(EncodeCloud({}, CloudCompressionConfig{0.01, 0}), std::invalid_argument);
}

double RotationErrorDeg(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
    return Eigen::AngleAxisd((a.inverse() * b).rotation()).angle() * 180.0 / M_PI;
}

TEST(CloudCompression, HdlPairRegistersWithinFiveCentimetresAndOneDegreeFromDecodedClouds) {
    RegistrationConfig config;
    config.voxel_m = 0.2;
    // What a robot sends: the cloud downsampled to the registration voxel, then encoded.
    const auto sent = [&](const std::string& name) {
        const PointCloud cloud = VoxelDownsample(Load("hdl_pair_fast_gicp/" + name), 0.2);
        const CloudDecodeResult d = DecodeCloud(EncodeCloud(cloud).bytes);
        EXPECT_TRUE(d.ok()) << d.error;
        return d.cloud;
    };
    const PointCloud target = sent("251370668.pcd");
    const PointCloud source = sent("251371071.pcd");
    Eigen::Matrix4d m;
    std::ifstream in(kLidar + "hdl_pair_fast_gicp/relative.txt");
    for (int k = 0; k < 16; ++k) in >> m(k / 4, k % 4);
    ASSERT_TRUE(in) << "relative.txt";
    const Eigen::Isometry3d reference(m);
    const RegistrationResult r =
        RegisterScans(source, target, Eigen::Isometry3d::Identity(), config);
    EXPECT_TRUE(r.accepted()) << static_cast<int>(r.status);
    EXPECT_LT((r.T_target_source.translation() - reference.translation()).norm(),
              kHdlMaxTranslationM);
    EXPECT_LT(RotationErrorDeg(r.T_target_source, reference), kHdlMaxRotationDeg);
}

}  // namespace
}  // namespace certislam::slam
