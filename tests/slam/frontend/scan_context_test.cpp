// Scan Context on real KITTI 00 and MulRan KAIST03 scans, and on scans rotated by known yaws.
#include "slam/frontend/scan_context.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

#include "slam/io/cloud_io.h"
#include "tests/data_paths.h"

namespace certislam::slam {
namespace {

const std::string kLidar = test_data::DataPath("lidar/");
constexpr double kSamePlaceMax = 0.15;      // issue 4: same place below 0.15
constexpr double kDifferentPlaceMin = 0.4;  // issue 4: different places above 0.4
constexpr double kSectorRad = 2.0 * std::numbers::pi / 60.0;

PointCloud Kitti(int frame) {
    char name[64];
    std::snprintf(name, sizeof(name), "kitti00_scancontext_samples/velodyne/%06d.bin", frame);
    CloudReadResult r = ReadKittiBin(kLidar + name);
    EXPECT_TRUE(r.ok()) << r.error;
    return std::move(r.cloud);
}

PointCloud Kaist(int index) {
    char name[64];
    std::snprintf(name, sizeof(name), "mulran_kaist03_keyframes/Scans/%06d.pcd", index);
    CloudReadResult r = ReadPcd(kLidar + name);
    EXPECT_TRUE(r.ok()) << r.error;
    return std::move(r.cloud);
}

PointCloud RotateZ(const PointCloud& cloud, double yaw) {
    const Eigen::Matrix3f R =
        Eigen::AngleAxisf(static_cast<float>(yaw), Eigen::Vector3f::UnitZ()).toRotationMatrix();
    PointCloud out;
    out.reserve(cloud.size());
    for (const auto& p : cloud) out.push_back(R * p);
    return out;
}

double AngleDiff(double a, double b) {
    return std::abs(std::remainder(a - b, 2 * std::numbers::pi));
}

class ScanContextKitti : public ::testing::Test {
  protected:
    static void SetUpTestSuite() {
        const ScanContextConfig config;
        for (int f : {94, 95, 198, 199}) sc_[f] = MakeScanContext(Kitti(f), config);
    }
    static inline std::map<int, ScanContext> sc_;
};

TEST_F(ScanContextKitti, DescriptorShapeAndKeys) {
    const ScanContext& sc = sc_[94];
    ASSERT_EQ(sc.bins.rows(), 20);
    ASSERT_EQ(sc.bins.cols(), 60);
    EXPECT_EQ(sc.ring_key.size(), 20);
    EXPECT_EQ(sc.sector_key.size(), 60);
    EXPECT_GT((sc.bins.array() > 0).count(), 300);  // a real street fills many bins
    EXPECT_FLOAT_EQ(sc.ring_key[3], sc.bins.row(3).mean());
}

TEST_F(ScanContextKitti, SamePlaceScansAreClose) {
    EXPECT_LT(ScanContextDistance(sc_[94], sc_[95]).distance, kSamePlaceMax);
    EXPECT_LT(ScanContextDistance(sc_[198], sc_[199]).distance, kSamePlaceMax);
    EXPECT_LT(ScanContextDistanceFast(sc_[94], sc_[95], ScanContextConfig{}).distance,
              kSamePlaceMax);
    EXPECT_LT(ScanContextDistanceFast(sc_[198], sc_[199], ScanContextConfig{}).distance,
              kSamePlaceMax);
}

TEST_F(ScanContextKitti, DifferentPlacesAreFar) {
    EXPECT_GT(ScanContextDistance(sc_[94], sc_[198]).distance, kDifferentPlaceMin);
    EXPECT_GT(ScanContextDistance(sc_[95], sc_[199]).distance, kDifferentPlaceMin);
    // The fast search can only miss the best shift, so it never reports a smaller distance.
    EXPECT_GE(ScanContextDistanceFast(sc_[94], sc_[198], 6).distance,
              ScanContextDistance(sc_[94], sc_[198]).distance);
}

TEST_F(ScanContextKitti, DistanceIsSymmetricInItsMinimum) {
    const ScanContextMatch ab = ScanContextDistance(sc_[94], sc_[95]);
    const ScanContextMatch ba = ScanContextDistance(sc_[95], sc_[94]);
    EXPECT_NEAR(ab.distance, ba.distance, 1e-9);
    EXPECT_EQ((ab.shift + ba.shift) % 60, 0);
}

// Columns made once per descriptor (as the loop matcher keeps them): the exhaustive search is
// the minimum of Eq. (5) over every shift, each shift's distance computed on its own.
TEST_F(ScanContextKitti, ColumnsMadeOnceGiveTheMinimumOverEveryShift) {
    for (const auto& [a, b] : {std::pair{94, 95}, {95, 94}, {94, 198}, {199, 95}}) {
        const ScanContextColumns qa(sc_[a]), cb(sc_[b]);
        const ScanContextMatch match = ScanContextDistance(qa, cb);
        double best = 2.0;
        for (int s = 0; s < 60; ++s)
            best = std::min(best, ScanContextDistanceAtShift(sc_[a], sc_[b], s));
        EXPECT_NEAR(match.distance, best, 1e-6) << a << " -> " << b;
        // The shift it names has that distance (float products: near-equal shifts may swap).
        EXPECT_NEAR(ScanContextDistanceAtShift(sc_[a], sc_[b], match.shift), best, 1e-6);
    }
}

// A scan rotated by k x 6 degrees: the recovered yaw is within one sector of the truth,
// for both searches, for k across the whole circle.
TEST(ScanContextRotation, RecoversYawWithinOneSector) {
    const PointCloud scan = Kitti(94);
    const ScanContextConfig config;
    const ScanContext original = MakeScanContext(scan, config);
    for (int k : {1, 5, 10, 17, 29, 30, 31, 44, 59}) {
        const double yaw = k * kSectorRad;
        const ScanContext rotated = MakeScanContext(RotateZ(scan, yaw), config);
        // query = rotated scan, candidate = original: T_candidate_query = Rz(-yaw).
        const ScanContextMatch full = ScanContextDistance(rotated, original);
        const ScanContextMatch fast = ScanContextDistanceFast(rotated, original, config);
        EXPECT_LE(AngleDiff(full.yaw_rad, -yaw), kSectorRad + 1e-9) << "k=" << k;
        EXPECT_LE(AngleDiff(fast.yaw_rad, -yaw), kSectorRad + 1e-9) << "k=" << k;
        EXPECT_LT(full.distance, 0.05) << "k=" << k;
    }
}

// Off-grid yaws (not multiples of the sector) also come back within one sector.
TEST(ScanContextRotation, RecoversOffGridYaw) {
    const PointCloud scan = Kitti(198);
    const ScanContextConfig config;
    const ScanContext original = MakeScanContext(scan, config);
    for (double deg : {-123.4, -47.0, 3.3, 88.8, 171.0}) {
        const double yaw = deg * std::numbers::pi / 180.0;
        const ScanContextMatch m =
            ScanContextDistance(MakeScanContext(RotateZ(scan, yaw), config), original);
        EXPECT_LE(AngleDiff(m.yaw_rad, -yaw), kSectorRad) << deg;
    }
}

TEST(ScanContextKaist, NeighbouringKeyframesAreClose) {
    const ScanContextConfig config;
    ScanContext previous = MakeScanContext(Kaist(0), config);
    for (int i = 1; i <= 20; ++i) {
        const ScanContext current = MakeScanContext(Kaist(i), config);
        EXPECT_LT(ScanContextDistance(previous, current).distance, kSamePlaceMax) << i;
        previous = current;
    }
}

TEST(ScanContextKaist, KaistIsFarFromKitti) {
    const ScanContextConfig config;
    EXPECT_GT(
        ScanContextDistance(MakeScanContext(Kaist(0), config), MakeScanContext(Kitti(94), config))
            .distance,
        kDifferentPlaceMin);
}

TEST(ScanContextWire, RoundTripAndRejectsGarbage) {
    const ScanContext sc = MakeScanContext(Kitti(95), ScanContextConfig{});
    const auto bytes = SerializeScanContext(sc);
    EXPECT_EQ(bytes.size(), 16u + 4u * (20 * 60 + 20));  // about 5 KB
    const auto back = DeserializeScanContext(bytes);
    ASSERT_TRUE(back.has_value());
    EXPECT_EQ(back->bins, sc.bins);
    EXPECT_EQ(back->ring_key, sc.ring_key);
    EXPECT_EQ(back->sector_key, sc.sector_key);
    auto cut = bytes;
    cut.pop_back();
    EXPECT_FALSE(DeserializeScanContext(cut).has_value());
    auto bad = bytes;
    bad[0] ^= 0xff;
    EXPECT_FALSE(DeserializeScanContext(bad).has_value());
}

TEST(ScanContextConfigTest, ValidateNamesField) {
    ScanContextConfig config;
    config.num_sectors = 1;
    try {
        config.Validate();
        FAIL() << "expected invalid_argument";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("num_sectors"), std::string::npos);
    }
}

TEST(ScanContextEmpty, EmptyCloudHasDistanceOne) {
    const ScanContext empty = MakeScanContext({}, ScanContextConfig{});
    const ScanContext real = MakeScanContext(Kitti(94), ScanContextConfig{});
    EXPECT_EQ(ScanContextDistance(empty, real).distance, 1.0);
}

}  // namespace
}  // namespace certislam::slam
