// Scan Context candidates of the mission pipeline: which keyframes query (the per-robot stride the
// loop-matcher actor uses too) and what they match.
#include "slam/frontend/loop_detection.h"

#include <gtest/gtest.h>

#include <set>
#include <utility>
#include <vector>

namespace certislam::slam {
namespace {

constexpr int kKeyframes = 12;

/// (query, match) candidates as ((robot, index), (robot, index)).
using CandidatePairs = std::set<std::pair<std::pair<int, int>, std::pair<int, int>>>;

/// A descriptor whose only non-empty ring is `ring`: two of them match (distance 0) when their
/// rings are equal; otherwise every column of one is orthogonal to the other's (distance 1).
ScanContext RingDescriptor(int ring, const ScanContextConfig& config) {
    ScanContext sc;
    sc.bins = ScanContextMatrix::Zero(config.num_rings, config.num_sectors);
    sc.bins.row(ring).setConstant(1.0F + 0.1F * static_cast<float>(ring));
    sc.ring_key = sc.bins.rowwise().mean();
    sc.sector_key = sc.bins.colwise().mean().transpose();
    sc.max_range_m = config.max_range_m;
    return sc;
}

/// Two robots whose keyframes alternate in time (robot 0 first); robot 1's keyframe i sees the
/// place of robot 0's keyframe i and no other.
struct TwoRobots {
    std::vector<std::vector<Keyframe>> robots;
    std::vector<std::vector<ScanContext>> descriptors;
};

TwoRobots AlternatingRobots(const ScanContextConfig& config) {
    TwoRobots team;
    team.robots.resize(2);
    team.descriptors.resize(2);
    for (int r = 0; r < 2; ++r) {
        for (int i = 0; i < kKeyframes; ++i) {
            Keyframe k;
            k.robot = r;
            k.index = i;
            k.stamp_ns = 2 * i + r;
            team.robots[r].push_back(k);
            team.descriptors[r].push_back(RingDescriptor(i, config));
        }
    }
    return team;
}

CandidatePairs Pairs(const std::vector<LoopCandidate>& candidates) {
    CandidatePairs pairs;
    for (const auto& c : candidates) {
        pairs.insert({{c.query.robot, c.query.index}, {c.match.robot, c.match.index}});
    }
    return pairs;
}

TEST(DetectCandidates, EveryKeyframeQueriesAtStrideOneAndFindsOnlyItsPlace) {
    LoopDetectionConfig config;
    config.intra_robot = false;
    const TwoRobots team = AlternatingRobots(config.scan_context);
    const auto candidates = DetectCandidates(team.descriptors, team.robots, config);
    ASSERT_EQ(candidates.size(), static_cast<size_t>(kKeyframes));
    for (const auto& c : candidates) {
        EXPECT_EQ(c.query.robot, 1);  // robot 0's keyframe i comes before robot 1's
        EXPECT_EQ(c.match.robot, 0);
        EXPECT_EQ(c.query.index, c.match.index);
        EXPECT_NEAR(c.sc_distance, 0.0, 1e-6);
    }
}

TEST(DetectCandidates, TheStrideCountsEachRobotsOwnKeyframesNotTheTeamsVisits) {
    LoopDetectionConfig config;
    config.intra_robot = false;
    config.query_stride = 3;
    const TwoRobots team = AlternatingRobots(config.scan_context);
    // Robot 1's keyframes 0, 3, 6 and 9 query; a stride over the team's stamp order would pick
    // robot 1's keyframes 1, 4, 7 and 10 (visits 3, 9, 15, 21) instead.
    CandidatePairs expected;
    for (int i = 0; i < kKeyframes; i += 3) expected.insert({{1, i}, {0, i}});
    EXPECT_EQ(Pairs(DetectCandidates(team.descriptors, team.robots, config)), expected);
}

TEST(DetectCandidates, IntraRobotPairsNeedTheMinimumGap) {
    LoopDetectionConfig config;
    config.min_intra_gap = 5;
    TwoRobots team = AlternatingRobots(config.scan_context);
    team.robots.resize(1);  // robot 0 alone
    team.descriptors.resize(1);
    // Robot 0 revisits the place of its keyframe 0 at keyframes 4 and 5: only 5 is far enough.
    team.descriptors[0][4] = RingDescriptor(0, config.scan_context);
    team.descriptors[0][5] = RingDescriptor(0, config.scan_context);
    const auto pairs = Pairs(DetectCandidates(team.descriptors, team.robots, config));
    EXPECT_EQ(pairs, (CandidatePairs{{{0, 5}, {0, 0}}}));
}

}  // namespace
}  // namespace certislam::slam
