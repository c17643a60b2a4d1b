// The DiSCo-style one-time alignment on hand-built odometry with known frame offsets.
#include "slam/backend/one_time_alignment.h"

#include <gtest/gtest.h>

namespace certislam::slam {
namespace {

constexpr double kExact = 1e-12;  ///< composition of a few exact rigid transforms

Eigen::Isometry3d Pose(double yaw, double x, double y, double z) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    T.translation() = Eigen::Vector3d(x, y, z);
    return T;
}

/// Robot trajectories in their own odometry frames (identity at keyframe 0) and their frames.
struct Team {
    std::vector<Eigen::Isometry3d> T_world_odom;
    std::vector<std::vector<Eigen::Isometry3d>> odometry;

    Eigen::Isometry3d World(int robot, int index) const {
        return T_world_odom[robot] * odometry[robot][index];
    }
    LoopClosure Loop(int ra, int ia, int rb, int ib) const {
        LoopClosure loop;
        loop.a = {ra, ia};
        loop.b = {rb, ib};
        loop.T_a_b = World(ra, ia).inverse() * World(rb, ib);
        return loop;
    }
};

Team MakeTeam(int robots) {
    Team team;
    for (int r = 0; r < robots; ++r) {
        team.T_world_odom.push_back(Pose(0.4 * r, 10.0 * r, -3.0 * r, 0.5 * r));
        std::vector<Eigen::Isometry3d> odom;
        for (int k = 0; k < 20; ++k) odom.push_back(Pose(0.1 * k, 2.0 * k, 0.3 * k * r, 0.0));
        team.odometry.push_back(odom);
    }
    return team;
}

TEST(OneTimeAlignment, ExactLoopRecoversTheTrueRelativeFrame) {
    const Team team = MakeTeam(2);
    const auto result = OneTimeAlignment(team.odometry, {team.Loop(0, 5, 1, 12)});
    ASSERT_TRUE(result.T_team_odom[1].has_value());
    const Eigen::Isometry3d truth = team.T_world_odom[0].inverse() * team.T_world_odom[1];
    EXPECT_TRUE(result.T_team_odom[1]->isApprox(truth, kExact));
    EXPECT_EQ(result.aligning_loop[1], 0);
    EXPECT_TRUE(
        result.poses[1][7].isApprox(team.T_world_odom[0].inverse() * team.World(1, 7), kExact));
}

TEST(OneTimeAlignment, LaterInterRobotLoopsAreNotUsed) {
    const Team team = MakeTeam(2);
    LoopClosure first = team.Loop(1, 3, 0, 4);          // robot 1 as tail: the inverse direction
    first.T_a_b = first.T_a_b * Pose(0.05, 0.5, 0, 0);  // an erroneous first encounter
    const auto with_later =
        OneTimeAlignment(team.odometry, {team.Loop(0, 1, 0, 9), first, team.Loop(0, 8, 1, 15)});
    const auto alone = OneTimeAlignment(team.odometry, {first});
    ASSERT_TRUE(with_later.T_team_odom[1] && alone.T_team_odom[1]);
    EXPECT_TRUE(with_later.T_team_odom[1]->isApprox(*alone.T_team_odom[1], kExact));
    EXPECT_EQ(with_later.aligning_loop[1], 1);  // the intra-robot loop 0 is skipped
    const Eigen::Isometry3d truth = team.T_world_odom[0].inverse() * team.T_world_odom[1];
    EXPECT_FALSE(with_later.T_team_odom[1]->isApprox(truth, 1e-3));  // the error stays
}

TEST(OneTimeAlignment, ChainsThroughAlignedRobotsAndLeavesStrangersInTheirOwnFrame) {
    const Team team = MakeTeam(4);
    const auto result =
        OneTimeAlignment(team.odometry, {team.Loop(2, 6, 1, 2), team.Loop(0, 10, 1, 11)});
    for (int r : {1, 2}) {
        ASSERT_TRUE(result.T_team_odom[r].has_value()) << r;
        EXPECT_TRUE(result.T_team_odom[r]->isApprox(
            team.T_world_odom[0].inverse() * team.T_world_odom[r], 1e-10));
    }
    EXPECT_FALSE(result.T_team_odom[3].has_value());
    EXPECT_TRUE(result.poses[3][4].isApprox(team.odometry[3][4], kExact));
}

}  // namespace
}  // namespace certislam::slam
