// Local search trapped on the scenarios made to trap it (issue 17): on tunnel-rendezvous and
// large-drift (poses only, ground-truth loops with noise), LM from odometry, whose robots set off
// half a turn apart, stops far above f* and the certificate refuses it with lambda_min < 0, while
// certified RBCD from the same graph is certified and LM from the one-time alignment reaches f*.
#include <gtest/gtest.h>

#include <string>

#include "certify/pipeline/mission.h"
#include "slam/sim/sim_scenarios.h"
#include "slam/sim/simulator.h"
#include "tests/param_names.h"

namespace certislam::certify {
namespace {

using Status = CertificateResult::Status;

constexpr double kTrappedAbove = 10.0;      // LM from odometry stops above this times f*
constexpr double kCostRelTolerance = 1e-6;  // LM from the alignment vs f* (relative)

MissionResult RunScenario(const std::string& name) {
    const auto scenario = slam::MakeScenario(name, 0, slam::ScenarioDefaultSeed(name));
    const slam::MissionGenerator generator(scenario->config);
    std::vector<std::vector<slam::Keyframe>> robots(generator.num_robots());
    std::vector<std::vector<Eigen::Isometry3d>> truth(generator.num_robots());
    for (int r = 0; r < generator.num_robots(); ++r) {
        for (int i = 0; i < generator.num_keyframes(r); ++i) {
            robots[r].push_back(generator.PoseOnly(r, i));
            truth[r].push_back(generator.T_world_sensor_truth(r, i));
        }
    }
    MissionConfig config;
    config.loops.source = slam::LoopSource::kGroundTruth;
    return RunMission(robots, truth, config);
}

class ScenarioTrap : public ::testing::TestWithParam<std::string> {};

TEST_P(ScenarioTrap, LocalSearchFromOdometryIsRefusedWhileRbcdIsCertified) {
    const MissionResult m = RunScenario(GetParam());
    ASSERT_EQ(m.solution.certificate.status, Status::kCertified);
    const double f_star = m.solution.cost;

    const LocalSearchRun& trapped = m.local_search_from_odometry;
    EXPECT_EQ(trapped.certificate.status, Status::kNotOptimal);
    EXPECT_LT(trapped.certificate.lambda_min, -trapped.certificate.eta);
    EXPECT_LE(trapped.certificate.gradient_norm, trapped.certificate.gradient_tolerance);
    EXPECT_GT(trapped.cost, kTrappedAbove * f_star);
    EXPECT_FALSE(trapped.certificate.has_bound);

    const LocalSearchRun& aligned = m.local_search_from_alignment;
    EXPECT_EQ(aligned.certificate.status, Status::kCertified);
    EXPECT_NEAR(aligned.cost, f_star, kCostRelTolerance * f_star);
}

INSTANTIATE_TEST_SUITE_P(Scenarios, ScenarioTrap,
                         ::testing::Values("tunnel-rendezvous", "large-drift"),
                         testing::DashesToUnderscores());

}  // namespace
}  // namespace certislam::certify
