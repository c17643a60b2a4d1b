// The mission pipeline on a small simulated two-robot mission (poses only, ground-truth loops
// with noise): joint graph shape, the one-time alignment leaves robot 0 as odometry, the
// certified solution is certified and no worse than both LM runs, and it beats odometry.
#include "certify/pipeline/mission.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "slam/eval/trajectory_metrics.h"
#include "slam/sim/simulator.h"

namespace certislam::certify {
namespace {

constexpr int kKeyframes = 90;                ///< per robot: small, still with inter-robot loops
constexpr double kCostRelTolerance = 1e-6;    ///< certified f vs LM f (relative)
constexpr double kSameTrajectoryTolM = 1e-9;  ///< robot 0's one-time alignment vs odometry

struct Mission {
    std::vector<std::vector<slam::Keyframe>> robots;
    std::vector<std::vector<Eigen::Isometry3d>> truth;  ///< T_world_sensor
    std::vector<slam::Trajectory> truth_team;           ///< in robot 0's odometry frame
};

Mission Simulate() {
    slam::SimulatorConfig config;
    config.seed = 3;
    const slam::MissionGenerator generator(config);
    Mission m;
    const Eigen::Isometry3d T_team_world = generator.T_world_odom(0).inverse();
    for (int r = 0; r < generator.num_robots(); ++r) {
        m.robots.emplace_back();
        m.truth.emplace_back();
        m.truth_team.emplace_back();
        for (int i = 0; i < std::min(kKeyframes, generator.num_keyframes(r)); ++i) {
            m.robots.back().push_back(generator.PoseOnly(r, i));
            m.truth.back().push_back(generator.T_world_sensor_truth(r, i));
            m.truth_team.back().push_back(
                {static_cast<double>(m.robots.back().back().stamp_ns) * 1e-9,
                 T_team_world * m.truth.back().back()});
        }
    }
    return m;
}

double TeamRmse(const Mission& m, const std::vector<slam::Trajectory>& est) {
    std::vector<slam::AssociatedPoses> pairs;
    for (size_t r = 0; r < est.size(); ++r) {
        pairs.push_back(slam::Associate(m.truth_team[r], est[r], {}));
    }
    return slam::EvaluateTeam(pairs, true).ate_rmse;
}

class MissionPipeline : public ::testing::Test {
  protected:
    static void SetUpTestSuite() {
        mission_ = new Mission(Simulate());
        MissionConfig config;
        config.loops.source = slam::LoopSource::kGroundTruth;
        result_ = new MissionResult(RunMission(mission_->robots, mission_->truth, config));
    }
    static void TearDownTestSuite() {
        delete result_;
        delete mission_;
    }
    static Mission* mission_;
    static MissionResult* result_;
};
Mission* MissionPipeline::mission_ = nullptr;
MissionResult* MissionPipeline::result_ = nullptr;

TEST_F(MissionPipeline, JointGraphHasOdometryChainsThenLoops) {
    const auto& g = result_->graph;
    int n = 0;
    for (const auto& r : mission_->robots) n += static_cast<int>(r.size());
    EXPECT_EQ(g.n, n);
    EXPECT_EQ(static_cast<int>(g.edges.size()), n - static_cast<int>(mission_->robots.size()) +
                                                    static_cast<int>(result_->loops.size()));
    EXPECT_GT(result_->loop_stats.inter_robot, 0);
    EXPECT_EQ(g.ids[kKeyframes].robot, 1);
    EXPECT_EQ(g.ids[kKeyframes].index, 0);
}

TEST_F(MissionPipeline, OneTimeAlignmentKeepsRobotZeroOdometry) {
    ASSERT_EQ(result_->one_time_alignment.size(), 2u);
    for (size_t i = 0; i < result_->odometry[0].size(); ++i) {
        EXPECT_LT((result_->one_time_alignment[0][i].T_world_body.translation() -
                   result_->odometry[0][i].T_world_body.translation())
                      .norm(),
                  kSameTrajectoryTolM);
    }
}

TEST_F(MissionPipeline, CertifiedAndNoWorseThanLocalSearch) {
    EXPECT_EQ(result_->status, MissionResult::Status::kOk);
    EXPECT_EQ(result_->solution.certificate.status, CertificateResult::Status::kCertified);
    const double f = result_->solution.cost;
    for (const LocalSearchRun* ls :
         {&result_->local_search_from_odometry, &result_->local_search_from_alignment}) {
        EXPECT_LE(f, ls->cost * (1 + kCostRelTolerance));
        EXPECT_LE(ls->cost, ls->initial_cost);
    }
}

TEST_F(MissionPipeline, CertifiedBeatsOdometryAndOneTimeAlignment) {
    const double certified = TeamRmse(*mission_, result_->certified);
    EXPECT_LT(certified, TeamRmse(*mission_, result_->one_time_alignment));
    EXPECT_LT(certified, TeamRmse(*mission_, result_->odometry));
}

TEST(MissionConfigTest, RejectsBadSettings) {
    MissionConfig config;
    config.noise.loop_sigma_t_m = 0.0;
    EXPECT_THROW(config.Validate(), std::invalid_argument);
    config = MissionConfig{};
    config.solver.rank = 2;
    EXPECT_THROW(config.Validate(), std::invalid_argument);
}

}  // namespace
}  // namespace certislam::certify
