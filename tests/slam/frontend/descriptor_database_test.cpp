// DescriptorDatabase: retrieval on real scans, exclusion of recent keyframes, and the growing
// k-d tree checked against brute force.
#include "slam/frontend/descriptor_database.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <set>
#include <string>

#include "slam/io/cloud_io.h"
#include "tests/data_paths.h"

namespace certislam::slam {
namespace {

const std::string kLidar = test_data::DataPath("lidar/");

ScanContext KaistDescriptor(int index) {
    char name[64];
    std::snprintf(name, sizeof(name), "mulran_kaist03_keyframes/Scans/%06d.pcd", index);
    const CloudReadResult r = ReadPcd(kLidar + name);
    EXPECT_TRUE(r.ok()) << r.error;
    return MakeScanContext(r.cloud, ScanContextConfig{});
}

ScanContext KittiDescriptor(int frame) {
    char name[64];
    std::snprintf(name, sizeof(name), "kitti00_scancontext_samples/velodyne/%06d.bin", frame);
    const CloudReadResult r = ReadKittiBin(kLidar + name);
    EXPECT_TRUE(r.ok()) << r.error;
    return MakeScanContext(r.cloud, ScanContextConfig{});
}

// A real descriptor with multiplicative noise on its bins and its columns rolled by `shift`.
ScanContext Perturbed(const ScanContext& base, std::mt19937& rng, int shift) {
    std::normal_distribution<float> noise(0.0f, 0.3f);
    ScanContext sc = base;
    const int n = static_cast<int>(sc.bins.cols());
    for (int r = 0; r < sc.bins.rows(); ++r) {
        for (int c = 0; c < n; ++c) {
            sc.bins(r, (c + shift) % n) = base.bins(r, c) * std::max(0.0f, 1.0f + noise(rng));
        }
    }
    sc.ring_key = sc.bins.rowwise().mean();
    sc.sector_key = sc.bins.colwise().mean().transpose();
    return sc;
}

TEST(DescriptorDatabase, KittiRevisitIsRetrievedAndOtherPlaceIsNot) {
    DescriptorDatabase db;
    ASSERT_TRUE(db.Add({0, 94}, KittiDescriptor(94)));
    ASSERT_TRUE(db.Add({0, 198}, KittiDescriptor(198)));
    // Query as if frame 95 were seen much later (index 1095), so 94 is not "recent".
    const auto hit = db.Detect({0, 1095}, KittiDescriptor(95));
    ASSERT_TRUE(hit.has_value());
    EXPECT_EQ(hit->id, (PoseId{0, 94}));
    EXPECT_LT(hit->match.distance, 0.15);
    const auto candidates = db.Query({0, 1199}, KittiDescriptor(199));
    ASSERT_EQ(candidates.size(), 1u);  // 94 is above max_distance
    EXPECT_EQ(candidates[0].id, (PoseId{0, 198}));
}

TEST(DescriptorDatabase, RecentOwnKeyframesAreExcludedButPeersAreNot) {
    DescriptorDatabaseConfig config;
    config.exclude_recent = 5;
    config.max_distance = 1.0;
    DescriptorDatabase db(config);
    std::vector<ScanContext> kaist;
    for (int i = 0; i <= 20; ++i) kaist.push_back(KaistDescriptor(i));
    for (int i = 0; i <= 20; ++i) ASSERT_TRUE(db.Add({0, i}, kaist[static_cast<size_t>(i)]));
    EXPECT_FALSE(db.Add({0, 3}, kaist[3]));  // duplicate id
    EXPECT_EQ(db.size(), 21u);

    const auto own = db.Query({0, 10}, kaist[10]);
    EXPECT_EQ(own.size(), 10u);  // still num_candidates real candidates after filtering
    for (const auto& c : own) EXPECT_GE(std::abs(c.id.index - 10), 5) << c.id.index;

    // The same scan seen by a peer (robot 1): its own twin is the best match.
    const auto peer = db.Detect({1, 10}, kaist[10]);
    ASSERT_TRUE(peer.has_value());
    EXPECT_EQ(peer->id, (PoseId{0, 10}));
    EXPECT_NEAR(peer->match.distance, 0.0, 1e-6);

    // An accept filter restricts the candidates (e.g. to one peer's entries).
    const auto none = db.Query({1, 10}, kaist[10], [](const PoseId& id) { return id.robot == 7; });
    EXPECT_TRUE(none.empty());
}

// Two robots on KAIST03: A has the even keyframes, B the odd ones (each ~1 m from an A one).
// Every B keyframe retrieves an A keyframe at most 2 indices away, below 0.15.
TEST(DescriptorDatabase, InterRobotRetrievalOnKaistSplit) {
    DescriptorDatabase db;
    std::vector<ScanContext> kaist;
    for (int i = 0; i <= 20; ++i) kaist.push_back(KaistDescriptor(i));
    for (int i = 0; i <= 20; i += 2) db.Add({0, i / 2}, kaist[static_cast<size_t>(i)]);
    for (int i = 1; i <= 20; i += 2) {
        const auto hit = db.Detect({1, i / 2}, kaist[static_cast<size_t>(i)]);
        ASSERT_TRUE(hit.has_value()) << i;
        EXPECT_LE(std::abs(2 * hit->id.index - i), 2) << i;
    }
}

// The tree grows one descriptor at a time; every query's k nearest admitted ring keys equal
// a brute-force search over what was inserted so far.
TEST(DescriptorDatabase, GrowingTreeMatchesBruteForce) {
    std::mt19937 rng(42);
    const std::vector<ScanContext> bases = {KittiDescriptor(94), KittiDescriptor(198),
                                            KaistDescriptor(0), KaistDescriptor(10)};
    DescriptorDatabaseConfig config;
    config.max_distance = 1.0;
    config.exclude_recent = 3;
    DescriptorDatabase db(config);
    std::vector<ScanContext> stored;
    std::uniform_int_distribution<int> pick(0, 3), shift(0, 59);
    for (int i = 0; i < 600; ++i) {
        const ScanContext sc = Perturbed(bases[static_cast<size_t>(pick(rng))], rng, shift(rng));
        if (i % 50 == 49) {
            const PoseId query{0, i};
            const auto got = db.Query(query, sc);
            std::vector<std::pair<float, int>> brute;
            for (int j = 0; j < i; ++j) {
                if (std::abs(j - i) < config.exclude_recent) continue;
                brute.push_back(
                    {(stored[static_cast<size_t>(j)].ring_key - sc.ring_key).squaredNorm(), j});
            }
            std::sort(brute.begin(), brute.end());
            std::set<int> expected, actual;
            for (int k = 0; k < config.num_candidates; ++k)
                expected.insert(brute[static_cast<size_t>(k)].second);
            for (const auto& c : got) actual.insert(c.id.index);
            EXPECT_EQ(actual, expected) << "after " << i << " insertions";
        }
        ASSERT_TRUE(db.Add({0, i}, sc));
        stored.push_back(sc);
    }
}

TEST(DescriptorDatabase, ConfigValidationNamesField) {
    DescriptorDatabaseConfig config;
    config.num_candidates = 0;
    EXPECT_THROW(DescriptorDatabase{config}, std::invalid_argument);
    try {
        config.Validate();
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("num_candidates"), std::string::npos);
    }
}

}  // namespace
}  // namespace certislam::slam
