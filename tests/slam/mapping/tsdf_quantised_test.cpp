// Tests of the TSDF's quantised layout (tsdf_serialize.h), what a mapper sends its peers: the
// same voxels with every value within half a step, and one refusal per rule of its reader.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>

#include "slam/mapping/tsdf_serialize.h"
#include "tests/slam/mapping/tsdf_test_scenes.h"

namespace certislam::slam {
namespace {

using testing::Pose;
using testing::ScanBoxes;

// Offsets of the quantised layout: the bits, the two steps, then the leaves.
constexpr std::size_t kBitsAt = kTsdfHeaderBytes;
constexpr std::size_t kSdfStepAt = kBitsAt + 4;
constexpr std::size_t kWeightStepAt = kBitsAt + 8;
constexpr std::size_t kCountAt = kBitsAt + 12;

TsdfVolume Scene() {
    TsdfConfig cfg;
    cfg.voxel_size_m = 0.4;
    TsdfVolume volume(cfg);
    for (const auto& T : {Pose(0, -2, 0, 0.0), Pose(3, -4, 0, 0.7), Pose(1, -3, 0, 0.3)}) {
        volume.Integrate(ScanBoxes(testing::GroundAndCube(-1.8), T), T);
    }
    return volume;
}

TsdfVoxelList Decode(const std::string& bytes) {
    std::string error;
    std::optional<TsdfVoxelList> list = DecodeTsdfVoxels(bytes, &error);
    EXPECT_TRUE(list.has_value()) << error;
    return list.value_or(TsdfVoxelList{});
}

float MaxAbs(const std::vector<float>& v) {
    float m = 0.0f;
    for (const float x : v) m = std::max(m, std::abs(x));
    return m;
}

template <typename T>
void Put(std::string& bytes, std::size_t at, T v) {
    std::memcpy(bytes.data() + at, &v, sizeof v);
}

void ExpectRefused(const std::string& bytes, std::size_t offset, const std::string& rule) {
    std::string error;
    EXPECT_FALSE(TsdfVolume::Deserialize(bytes, &error).has_value());
    EXPECT_NE(error.find("byte offset " + std::to_string(offset) + ":"), std::string::npos)
        << error;
    EXPECT_NE(error.find(rule), std::string::npos) << error;
}

TEST(TsdfQuantised, KeepsEveryVoxelAndMovesEachValueByAtMostHalfAStep) {
    const TsdfVolume volume = Scene();
    const std::string exact_bytes = volume.Serialize();
    const TsdfVoxelList exact = Decode(exact_bytes);
    ASSERT_GT(exact.sdf.size(), 1000u);
    for (const int bits : {16, 8}) {
        const std::string bytes = volume.Serialize(bits);
        EXPECT_LT(bytes.size(), exact_bytes.size() / 2) << bits;
        const TsdfVoxelList q = Decode(bytes);
        ASSERT_EQ(q.origins, exact.origins) << bits;
        ASSERT_EQ(q.masks, exact.masks) << bits;
        ASSERT_EQ(q.sdf.size(), exact.sdf.size()) << bits;
        const float sdf_step = MaxAbs(exact.sdf) / float((1 << (bits - 1)) - 1);
        const float weight_step = MaxAbs(exact.weight) / 255.0f;
        double sdf_err = 0.0, weight_err = 0.0;
        for (std::size_t i = 0; i < q.sdf.size(); ++i) {
            sdf_err = std::max(sdf_err, double(std::abs(q.sdf[i] - exact.sdf[i])));
            weight_err = std::max(weight_err, double(std::abs(q.weight[i] - exact.weight[i])));
            if (exact.weight[i] > 0.0f) {
                EXPECT_GT(q.weight[i], 0.0f) << "voxel " << i;
            }
        }
        // half a step, plus the float rounding of q * step at the largest distance
        const double ulp = std::numeric_limits<float>::epsilon() * MaxAbs(exact.sdf);
        EXPECT_LE(sdf_err, 0.5 * sdf_step + ulp) << bits;
        EXPECT_GT(sdf_err, 0.0) << bits;  // lossy: it is not the exact layout again
        EXPECT_LE(weight_err, weight_step * (1 + 1e-5)) << bits;  // a small weight: one step
    }
    EXPECT_LT(volume.Serialize(8).size(), volume.Serialize(16).size());
}

TEST(TsdfQuantised, APeersMeshFromSixteenBitsIsTheSameSurface) {
    TsdfVolume volume = Scene();
    std::string error;
    auto back = TsdfVolume::Deserialize(volume.Serialize(16), &error);
    ASSERT_TRUE(back.has_value()) << error;
    const TriangleMesh a = volume.ExtractMesh();
    const TriangleMesh b = back->ExtractMesh();
    // A distance within a step of 0 may change sign, a weight near min_mesh_weight may cross
    // it: a few triangles differ; every other vertex stays within a millimetre.
    ASSERT_GT(a.vertices.size(), 1000u);
    EXPECT_NEAR(double(b.triangles.size()), double(a.triangles.size()),
                0.01 * double(a.triangles.size()));
    std::size_t matched = 0;
    for (const auto& v : b.vertices) {
        double nearest = std::numeric_limits<double>::infinity();
        for (const auto& u : a.vertices) nearest = std::min(nearest, double((u - v).norm()));
        matched += nearest < 1e-3 ? 1 : 0;
    }
    EXPECT_GE(double(matched), 0.99 * double(b.vertices.size()));
    // Re-sent by the peer: a quantised volume's own lossless bytes decode to the same voxels.
    const auto again = TsdfVolume::Deserialize(back->Serialize(), &error);
    ASSERT_TRUE(again.has_value()) << error;
    EXPECT_TRUE(again->SameVoxels(*back));
}

TEST(TsdfQuantised, RefusesBadBitsStepsAndValues) {
    const std::string bytes = Scene().Serialize(8);
    std::string bits = bytes;
    Put<std::uint32_t>(bits, kBitsAt, 12);
    ExpectRefused(bits, kBitsAt, "distance bits 12: must be 8 or 16");
    for (const float step :
         {std::numeric_limits<float>::quiet_NaN(), -1.0f, std::numeric_limits<float>::infinity()}) {
        for (const std::size_t at : {kSdfStepAt, kWeightStepAt}) {
            std::string bad = bytes;
            Put(bad, at, step);
            ExpectRefused(bad, kSdfStepAt, "quantisation steps");
        }
    }
    std::uint64_t leaves = 0;
    std::memcpy(&leaves, bytes.data() + kCountAt, sizeof leaves);
    const std::size_t values_at = kCountAt + 8 + kTsdfLeafBytes * leaves;
    std::string low = bytes;
    low[values_at + 5] = char(-128);  // int8's extra negative value
    ExpectRefused(low, values_at + 5, "distance of active voxel 5 is -128 steps");
    std::string heavy = bytes;  // weights beyond max_weight
    Put(heavy, kWeightStepAt, TsdfConfig{}.max_weight);
    std::string error;
    EXPECT_FALSE(TsdfVolume::Deserialize(heavy, &error).has_value());
    EXPECT_NE(error.find("weight of active voxel"), std::string::npos) << error;
    // Cut short, its length patched: the values no longer fill the rest.
    std::string cut = bytes.substr(0, bytes.size() - 3);
    Put<std::uint64_t>(cut, 72, cut.size() - kTsdfHeaderBytes);
    EXPECT_FALSE(TsdfVolume::Deserialize(cut, &error).has_value());
    EXPECT_NE(error.find("bytes of values"), std::string::npos) << error;
}

}  // namespace
}  // namespace certislam::slam
