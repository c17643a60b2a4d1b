// Tests of the TSDF's checked voxel formats (tsdf_serialize.h): an exact, canonical round trip,
// the quantised layout's bounded error, and one refusal per rule of the reader, each naming the
// byte offset the rule broke at.
#include "slam/mapping/tsdf_serialize.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>

#include "tests/slam/mapping/tsdf_test_scenes.h"

namespace certislam::slam {
namespace {

using testing::Pose;
using testing::ScanBoxes;

// The layout's offsets in the bytes of one volume (tsdf_serialize.h).
struct Layout {
    std::size_t leaves = 0, active = 0;
    std::size_t count_at = kTsdfHeaderBytes;
    std::size_t origins_at = kTsdfHeaderBytes + 8;
    std::size_t masks_at() const { return origins_at + 12 * leaves; }
    std::size_t sdf_at() const { return masks_at() + 8 * kTsdfMaskWords * leaves; }
    std::size_t weight_at() const { return sdf_at() + 4 * active; }
};

Layout LayoutOf(const std::string& bytes) {
    Layout l;
    std::uint64_t count;
    std::memcpy(&count, bytes.data() + l.count_at, sizeof count);
    l.leaves = count;
    l.active = (bytes.size() - l.sdf_at()) / 8;
    return l;
}

// A volume with a few hundred leaves: the ground and a cube seen from two poses.
TsdfVolume SmallVolume() {
    TsdfConfig cfg;
    cfg.voxel_size_m = 0.4;
    TsdfVolume volume(cfg);
    for (const auto& T : {Pose(0, -2, 0, 0.0), Pose(3, -4, 0, 0.7)}) {
        volume.Integrate(ScanBoxes(testing::GroundAndCube(-1.8), T), T);
    }
    return volume;
}

template <typename T>
void Put(std::string& bytes, std::size_t at, T v) {
    std::memcpy(bytes.data() + at, &v, sizeof v);
}

// Sets active voxel `i` of a byte-planed float block of `n` values at `block_at` to `v`.
void PutPlaned(std::string& bytes, std::size_t block_at, std::size_t n, std::size_t i, float v) {
    unsigned char b[4];
    std::memcpy(b, &v, 4);
    for (std::size_t p = 0; p < 4; ++p) bytes[block_at + p * n + i] = char(b[p]);
}

// Refused, with an error naming `offset` and containing `rule`.
void ExpectRefused(const std::string& bytes, std::size_t offset, const std::string& rule) {
    std::string error;
    EXPECT_FALSE(TsdfVolume::Deserialize(bytes, &error).has_value());
    EXPECT_NE(error.find("byte offset " + std::to_string(offset) + ":"), std::string::npos)
        << error;
    EXPECT_NE(error.find(rule), std::string::npos) << error;
}

TEST(TsdfBytes, RoundTripIsVoxelExactAndCanonical) {
    TsdfVolume volume = SmallVolume();
    const std::string bytes = volume.Serialize();
    const Layout l = LayoutOf(bytes);
    EXPECT_EQ(l.leaves, volume.Stats().leaf_blocks);
    EXPECT_EQ(l.active, volume.Stats().active_voxels);
    std::string error;
    auto back = TsdfVolume::Deserialize(bytes, &error);
    ASSERT_TRUE(back.has_value()) << error;
    EXPECT_TRUE(back->SameVoxels(volume));
    EXPECT_EQ(back->Stats().leaf_blocks, l.leaves);
    EXPECT_EQ(back->Serialize(), bytes);  // one encoding per volume
    const TriangleMesh a = volume.ExtractMesh(), b = back->ExtractMesh();
    EXPECT_EQ(a.vertices, b.vertices);
    EXPECT_EQ(a.triangles, b.triangles);
}

TEST(TsdfBytes, RefusesTruncatedBytesEvenWithAConsistentLength) {
    const std::string bytes = SmallVolume().Serialize();
    const Layout l = LayoutOf(bytes);
    ExpectRefused(bytes.substr(0, 50), 50, "truncated header");
    ExpectRefused(bytes.substr(0, bytes.size() - 1), 72, "does not match");
    // Cut inside the count, the origins, the masks and the values, the header's length patched.
    for (const std::size_t cut :
         {l.count_at + 3, l.origins_at + 5, l.masks_at() + 9, l.sdf_at() + 4, bytes.size() - 4}) {
        std::string cut_bytes = bytes.substr(0, cut);
        Put<std::uint64_t>(cut_bytes, 72, cut - kTsdfHeaderBytes);
        std::string error;
        EXPECT_FALSE(TsdfVolume::Deserialize(cut_bytes, &error).has_value()) << "cut " << cut;
        EXPECT_NE(error.find("byte offset"), std::string::npos) << error;
    }
}

TEST(TsdfBytes, RefusesALeafCountTheBytesCannotHold) {
    const std::string bytes = SmallVolume().Serialize();
    const Layout l = LayoutOf(bytes);
    for (const std::uint64_t count :
         {std::uint64_t{1} << 60, ~std::uint64_t{0}, std::uint64_t{bytes.size()}}) {
        std::string bad = bytes;
        Put(bad, l.count_at, count);
        ExpectRefused(bad, l.count_at, "leaf count");
    }
    // One leaf fewer: its mask is read as origins, and the values no longer fill the rest.
    std::string fewer = bytes;
    Put<std::uint64_t>(fewer, l.count_at, l.leaves - 1);
    std::string error;
    EXPECT_FALSE(TsdfVolume::Deserialize(fewer, &error).has_value());
    EXPECT_NE(error.find("byte offset"), std::string::npos) << error;
}

TEST(TsdfBytes, RefusesADuplicateLeaf) {
    std::string bytes = SmallVolume().Serialize();
    const Layout l = LayoutOf(bytes);
    ASSERT_GE(l.leaves, 3u);
    std::memcpy(bytes.data() + l.origins_at + 24, bytes.data() + l.origins_at, 12);
    ExpectRefused(bytes, l.origins_at + 24, "duplicate leaf origin");
}

TEST(TsdfBytes, RefusesOriginsOffTheLeafGridOrTooFar) {
    const std::string bytes = SmallVolume().Serialize();
    const Layout l = LayoutOf(bytes);
    std::string unaligned = bytes;
    Put<std::int32_t>(unaligned, l.origins_at + 12 + 4, 12);  // y of leaf 1
    ExpectRefused(unaligned, l.origins_at + 12, "not a multiple of 8");
    std::string far = bytes;
    Put<std::int32_t>(far, l.origins_at + 8, -kTsdfMaxOriginVoxels - 8);  // z of leaf 0
    ExpectRefused(far, l.origins_at, "beyond");
}

// Leaf l moved to (node * (l / per_node) + 8 * (l % per_node), 0, 0).
std::string Spread(std::string bytes, std::int32_t node, std::size_t per_node) {
    const Layout l = LayoutOf(bytes);
    for (std::size_t i = 0; i < l.leaves; ++i) {
        const auto x = std::int32_t(node * std::int32_t(i / per_node) + 8 * (i % per_node));
        Put(bytes, l.origins_at + 12 * i, x);
        Put<std::int32_t>(bytes, l.origins_at + 12 * i + 4, 0);
        Put<std::int32_t>(bytes, l.origins_at + 12 * i + 8, 0);
    }
    return bytes;
}

TEST(TsdfBytes, RefusesLeavesScatteredOverTreeNodes) {
    const std::string bytes = SmallVolume().Serialize();
    const Layout l = LayoutOf(bytes);
    ASSERT_GE(l.leaves, 64 * 8 / 3u);  // enough leaves that 16 a node break the top-node rule
    std::string error;
    // 16 leaves a 128^3 node, every such node in a 4096^3 node of its own: the top rule.
    ExpectRefused(Spread(bytes, 4096, 16), l.origins_at, "tree nodes of 4096^3 voxels");
    // One leaf a 128^3 node: the middle rule.
    ExpectRefused(Spread(bytes, 128, 1), l.origins_at, "tree nodes of 128^3 voxels");
    // 16 leaves a 128^3 node, all in one 4096^3 node: accepted.
    EXPECT_TRUE(TsdfVolume::Deserialize(Spread(bytes, 128, 16), &error).has_value()) << error;
}

TEST(TsdfBytes, RefusesALeafWithoutActiveVoxels) {
    std::string bytes = SmallVolume().Serialize();
    const Layout l = LayoutOf(bytes);
    const std::size_t mask_at = l.masks_at() + 8 * kTsdfMaskWords;  // leaf 1's
    std::memset(bytes.data() + mask_at, 0, 8 * kTsdfMaskWords);
    ExpectRefused(bytes, mask_at, "no active voxel");
}

TEST(TsdfBytes, RefusesNonFiniteDistancesAndWeightsOutOfRange) {
    const std::string bytes = SmallVolume().Serialize();
    const Layout l = LayoutOf(bytes);
    constexpr float kNan = std::numeric_limits<float>::quiet_NaN();
    constexpr float kInf = std::numeric_limits<float>::infinity();
    for (const float v : {kNan, kInf, -kInf}) {
        std::string bad = bytes;
        PutPlaned(bad, l.sdf_at(), l.active, 7, v);
        ExpectRefused(bad, l.sdf_at(), "distance of active voxel 7 is not finite");
    }
    const float max_weight = TsdfConfig{}.max_weight;
    for (const float w : {kNan, -1.0f, std::nextafter(max_weight, kInf), kInf}) {
        std::string bad = bytes;
        PutPlaned(bad, l.weight_at(), l.active, 3, w);
        ExpectRefused(bad, l.weight_at(), "weight of active voxel 3");
    }
    std::string top = bytes;  // the bounds themselves are weights a volume can hold
    PutPlaned(top, l.weight_at(), l.active, 3, max_weight);
    PutPlaned(top, l.weight_at(), l.active, 4, 0.0f);
    std::string error;
    EXPECT_TRUE(TsdfVolume::Deserialize(top, &error).has_value()) << error;
}

TEST(TsdfBytes, RefusesHeaderSettingsThatAreNotAValidConfig) {
    const std::string bytes = SmallVolume().Serialize();
    std::string bad_magic = bytes;
    bad_magic[7] = '2';  // CSTSDF02, the former format (an OpenVDB stream)
    ExpectRefused(bad_magic, 0, "bad magic");
    std::string nan_weight = bytes;
    Put(nan_weight, 56, std::numeric_limits<float>::quiet_NaN());  // max_weight
    ExpectRefused(nan_weight, 56, "not finite");
    std::string tiny_voxel = bytes;
    Put(tiny_voxel, 8, 1e-9);  // voxel_size_m
    ExpectRefused(tiny_voxel, 0, "voxel_size_m");
}

// The quantised layout, what a mapper sends its peers: the same voxels with every value within
// half a step, and one refusal per rule of its reader.

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
