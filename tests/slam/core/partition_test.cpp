// Partitions of a pose graph into robots, and its public poses, on hand-built graphs.
#include "slam/core/partition.h"

#include <gtest/gtest.h>

namespace certislam::slam {
namespace {

/// Robot 0 owns poses 0-2, robot 1 poses 3-4; odometry chains plus the given extra edges.
PoseGraph TwoRobots(const std::vector<std::pair<int, int>>& extra) {
    PoseGraph graph;
    graph.n = 5;
    graph.ids = {{0, 0}, {0, 1}, {0, 2}, {1, 0}, {1, 1}};
    auto add = [&](int i, int j) {
        RelativePoseMeasurement e;
        e.i = i;
        e.j = j;
        graph.edges.push_back(e);
    };
    add(0, 1);
    add(1, 2);
    add(3, 4);
    for (const auto& [i, j] : extra) add(i, j);
    return graph;
}

TEST(Partition, FromIdsSplitsAtTheRobotBoundary) {
    const Partition p = PartitionFromIds(TwoRobots({}));
    ASSERT_EQ(p.num_robots(), 2);
    EXPECT_EQ(p.size(0), 3);
    EXPECT_EQ(p.size(1), 2);
    EXPECT_EQ(p.RobotOf(3), 1);
}

TEST(Partition, PublicPosesAreThoseOfInterRobotEdgesCountedOnce) {
    EXPECT_EQ(CountPublicPoses(TwoRobots({})), 0);
    EXPECT_EQ(CountPublicPoses(TwoRobots({{0, 2}})), 0);          // intra-robot loop
    EXPECT_EQ(CountPublicPoses(TwoRobots({{2, 3}})), 2);          // one inter-robot edge
    EXPECT_EQ(CountPublicPoses(TwoRobots({{2, 3}, {2, 4}})), 3);  // pose 2 shared twice
}

}  // namespace
}  // namespace certislam::slam
