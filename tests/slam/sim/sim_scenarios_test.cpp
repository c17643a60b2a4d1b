// The named scenarios: known names build missions of the asked size with fixed seeds, the
// tunnel rendezvous starts robot 1 inside the tunnel and has several hundred keyframes per robot,
// its robots and large-drift's set off half a turn apart, robots start one after another, and the
// tunnel's odometry slip shortens the along-track motion there.
#include "slam/sim/sim_scenarios.h"

#include <gtest/gtest.h>

namespace certislam::slam {
namespace {

bool InTunnel(const SimStreets& st, const Eigen::Vector3d& p) {
    return p.x() > st.tunnel_x_begin && p.x() < st.tunnel_x_end &&
           std::abs(p.y()) < st.tunnel_half_width;
}

TEST(SimScenarios, EveryNameBuildsItsDefaultTeam) {
    for (const auto& name : ScenarioNames()) {
        const auto s = MakeScenario(name, 0, 1);
        ASSERT_TRUE(s.has_value()) << name;
        EXPECT_EQ(s->name, name);
        EXPECT_FALSE(s->description.empty());
        const MissionGenerator generator(s->config);
        EXPECT_EQ(generator.num_robots(), ScenarioDefaultRobots(name)) << name;
        for (int r = 0; r < generator.num_robots(); ++r) {
            EXPECT_GT(generator.num_keyframes(r), 20) << name << " robot " << r;
        }
    }
    EXPECT_EQ(ScenarioNames().front(), "tunnel-rendezvous");
    EXPECT_EQ(ScenarioDefaultRobots("swarm"), 8);
    EXPECT_NE(ScenarioDefaultSeed("tunnel-rendezvous"), 0u);
    EXPECT_EQ(ScenarioDefaultSeed("city"), 1u);
}

TEST(SimScenarios, UnknownNameGivesNothing) {
    EXPECT_FALSE(MakeScenario("moon", 2, 1).has_value());
    EXPECT_EQ(ScenarioDefaultRobots("moon"), 0);
}

TEST(SimScenarios, TunnelRendezvousStartsRobotOneInsideTheTunnel) {
    const auto s = MakeScenario("tunnel-rendezvous", 2, 1);
    ASSERT_TRUE(s.has_value());
    const MissionGenerator generator(s->config);
    EXPECT_TRUE(InTunnel(generator.streets(), generator.T_world_sensor_truth(1, 0).translation()));
    EXPECT_FALSE(InTunnel(generator.streets(), generator.T_world_sensor_truth(0, 0).translation()));
}

TEST(SimScenarios, TunnelRendezvousHasSeveralHundredKeyframesPerRobot) {
    constexpr int kSeveralHundred = 200;
    const auto s = MakeScenario("tunnel-rendezvous", 2, ScenarioDefaultSeed("tunnel-rendezvous"));
    ASSERT_TRUE(s.has_value());
    const MissionGenerator generator(s->config);
    for (int r = 0; r < generator.num_robots(); ++r) {
        EXPECT_GE(generator.num_keyframes(r), kSeveralHundred) << "robot " << r;
    }
    EXPECT_GE(s->loop_query_stride, 1);
}

TEST(SimScenarios, TunnelAndLargeDriftRobotsSetOffHalfATurnApart) {
    constexpr double kMinOffsetRad = 3.0;  // close to pi: the odometry frames face each other
    for (const char* name : {"tunnel-rendezvous", "large-drift"}) {
        const auto s = MakeScenario(name, 2, 1);
        ASSERT_TRUE(s.has_value());
        const MissionGenerator generator(s->config);
        const Eigen::Matrix3d R_0_1 =
            generator.T_world_odom(0).linear().transpose() * generator.T_world_odom(1).linear();
        EXPECT_GT(Eigen::AngleAxisd(R_0_1).angle(), kMinOffsetRad) << name;
    }
}

TEST(SimScenarios, SequentialRobotsStartAfterThePreviousEnds) {
    const auto s = MakeScenario("city", 2, 1, true);
    ASSERT_TRUE(s.has_value());
    const MissionGenerator generator(s->config);
    const int last = generator.num_keyframes(0) - 1;
    EXPECT_GT(generator.PoseOnly(1, 0).stamp_ns, generator.PoseOnly(0, last).stamp_ns);
    const auto together = MakeScenario("city", 2, 1, false);
    EXPECT_EQ(together->config.robot_start_interval_s, 0.0);
}

TEST(SimScenarios, TunnelSlipShortensOdometryInTheTunnelOnly) {
    auto s = MakeScenario("tunnel-rendezvous", 1, 3, false);
    ASSERT_TRUE(s.has_value());
    const double slip = s->config.tunnel_slip;
    ASSERT_GT(slip, 0.0);
    s->config.drift = SimOdometryDriftConfig{0, 0, 0, 0, 0, 0, 0};  // odometry exact but slip
    const MissionGenerator slipping(s->config);
    for (int i = 1; i < slipping.num_keyframes(0); ++i) {
        const auto& a = slipping.T_world_sensor_truth(0, i - 1);
        const auto& b = slipping.T_world_sensor_truth(0, i);
        const double truth = (b.translation() - a.translation()).norm();
        const double odom = (slipping.PoseOnly(0, i).T_odom_sensor.translation() -
                             slipping.PoseOnly(0, i - 1).T_odom_sensor.translation())
                                .norm();
        const bool inside = InTunnel(slipping.streets(), 0.5 * (a.translation() + b.translation()));
        EXPECT_NEAR(odom, inside ? (1.0 - slip) * truth : truth, 1e-6) << i;
    }
}

}  // namespace
}  // namespace certislam::slam
