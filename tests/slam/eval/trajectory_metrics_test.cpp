// ATE/RPE on hand-built trajectories whose errors are known in closed form.
#include "slam/eval/trajectory_metrics.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace certislam::slam {
namespace {

constexpr double kExact = 1e-9;  ///< tolerance for figures that are exact up to rounding

/// A non-planar helix, so the Umeyama alignment is unique.
Trajectory Helix(int n, double t0 = 0.0) {
    Trajectory traj;
    for (int k = 0; k < n; ++k) {
        StampedPose p;
        p.stamp_s = t0 + 0.1 * k;
        const double a = 0.2 * k;
        p.T_world_body.linear() = Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ()).toRotationMatrix();
        p.T_world_body.translation() = Eigen::Vector3d(10 * std::cos(a), 10 * std::sin(a), 0.5 * k);
        traj.push_back(p);
    }
    return traj;
}

Eigen::Isometry3d KnownTransform() {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
    T.translation() = Eigen::Vector3d(5, -3, 2);
    return T;
}

Trajectory Transformed(const Trajectory& traj, const Eigen::Isometry3d& T) {
    Trajectory out = traj;
    for (auto& p : out) p.T_world_body = T * p.T_world_body;
    return out;
}

TEST(TrajectoryMetrics, RigidlyMovedTrajectoryHasZeroAteAfterSe3Alignment) {
    const Trajectory gt = Helix(50);
    const Trajectory est = Transformed(gt, KnownTransform());
    const auto pairs = Associate(gt, est, {});
    ASSERT_EQ(pairs.gt.size(), 50u);
    const auto aligned = EvaluateTeam({pairs}, true);
    EXPECT_NEAR(aligned.ate_rmse, 0.0, 1e-8);
    EXPECT_TRUE(aligned.T_gt_est.isApprox(KnownTransform().inverse(), 1e-9));
    EXPECT_NEAR(aligned.rpe_rmse, 0.0, 1e-8);
}

TEST(TrajectoryMetrics, UnalignedAteOfAPureTranslationIsItsLength) {
    const Trajectory gt = Helix(30);
    Eigen::Isometry3d shift = Eigen::Isometry3d::Identity();
    shift.translation() = Eigen::Vector3d(3, 4, 0);  // 5 m
    const auto pairs = Associate(gt, Transformed(gt, shift), {});
    EXPECT_NEAR(EvaluateTeam({pairs}, false).ate_rmse, 5.0, kExact);
    EXPECT_NEAR(EvaluateTeam({pairs}, true).ate_rmse, 0.0, 1e-8);
}

TEST(TrajectoryMetrics, UnalignedAteOfARotationMatchesClosedForm) {
    const Trajectory gt = Helix(40);
    const Eigen::Isometry3d T = KnownTransform();
    const auto pairs = Associate(gt, Transformed(gt, T), {});
    double sum = 0.0;
    for (const auto& p : gt) {
        sum += (p.T_world_body.translation() - T * p.T_world_body.translation()).squaredNorm();
    }
    EXPECT_NEAR(EvaluateTeam({pairs}, false).ate_rmse, std::sqrt(sum / 40.0), kExact);
}

TEST(TrajectoryMetrics, AlternatingPerturbationGivesItsAmplitudeAsRmse) {
    // +-d along the normal of a planar circle: the best rigid alignment is the identity (the
    // perturbation has zero mean and no moment), so ATE = d and consecutive RPE = 2d.
    const double d = 0.3;
    Trajectory gt;
    for (int k = 0; k < 40; ++k) {
        StampedPose p;
        p.stamp_s = k;
        const double a = 2 * M_PI * k / 40.0;
        p.T_world_body.translation() = Eigen::Vector3d(10 * std::cos(a), 10 * std::sin(a), 0);
        gt.push_back(p);
    }
    Trajectory est = gt;
    for (size_t k = 0; k < est.size(); ++k) {
        est[k].T_world_body.translation().z() += (k % 2 == 0) ? d : -d;
    }
    const auto pairs = Associate(gt, est, {});
    const auto team = EvaluateTeam({pairs}, true);
    EXPECT_NEAR(team.ate_rmse, d, 1e-9);
    EXPECT_NEAR(team.rpe_rmse, 2 * d, 1e-9);
}

TEST(TrajectoryMetrics, AssociatesByNearestStampWithinMaxDiff) {
    const Trajectory gt = Helix(20);    // stamps 0.0, 0.1, ...
    Trajectory est = Helix(20, 0.004);  // 4 ms late: matched
    est.push_back(est.back());
    est.back().stamp_s += 0.05;  // no gt stamp within 10 ms
    AssociationConfig config;
    EXPECT_EQ(Associate(gt, est, config).gt.size(), 20u);
    config.max_diff_s = 0.001;
    EXPECT_EQ(Associate(gt, est, config).gt.size(), 0u);
    config.by_index = true;
    EXPECT_EQ(Associate(gt, est, config).gt.size(), 20u);
}

TEST(TrajectoryMetrics, JointAlignmentUsesOneTransformForTheTeam) {
    // Robot 1 is rigidly moved on its own: each alone aligns perfectly, jointly it cannot.
    const Trajectory gt0 = Helix(30), gt1 = Helix(30, 10.0);
    Eigen::Isometry3d shift = Eigen::Isometry3d::Identity();
    shift.translation() = Eigen::Vector3d(0, 0, 2);
    const auto p0 = Associate(gt0, gt0, {});
    const auto p1 = Associate(gt1, Transformed(gt1, shift), {});
    const auto team = EvaluateTeam({p0, p1}, true);
    ASSERT_EQ(team.robots.size(), 2u);
    EXPECT_NEAR(team.robots[0].ate_rmse_own, 0.0, 1e-8);
    EXPECT_NEAR(team.robots[1].ate_rmse_own, 0.0, 1e-8);
    EXPECT_GT(team.ate_rmse, 0.5);  // a 2 m offset between the robots cannot be aligned away
    EXPECT_EQ(team.pairs, 60);
}

TEST(TrajectoryMetrics, NoPairsIsAStatusNotACrash) {
    const auto team = EvaluateTeam({AssociatedPoses{}}, true);
    EXPECT_EQ(team.status, TeamErrors::Status::kNoPairs);
    AssociationConfig bad;
    bad.max_diff_s = -1;
    EXPECT_THROW(bad.Validate(), std::invalid_argument);
}

TEST(TrajectoryMetrics, AlignTeamMovesARigidlyMovedTeamOntoItsGroundTruth) {
    const std::vector<Trajectory> gt = {Helix(30), Helix(30, 10.0)};
    const Eigen::Isometry3d T = KnownTransform();
    const AlignedTeam team = AlignTeam(gt, {Transformed(gt[0], T), Transformed(gt[1], T)});
    ASSERT_EQ(team.ate_rmse.size(), 2u);
    ASSERT_EQ(team.aligned.size(), 2u);
    for (size_t r = 0; r < 2; ++r) {
        EXPECT_NEAR(team.ate_rmse[r], 0.0, 1e-8);
        ASSERT_EQ(team.aligned[r].size(), gt[r].size());
        for (size_t k = 0; k < gt[r].size(); ++k) {
            EXPECT_TRUE(team.aligned[r][k].T_world_body.isApprox(gt[r][k].T_world_body, 1e-8));
            EXPECT_EQ(team.aligned[r][k].stamp_s, gt[r][k].stamp_s);
        }
    }
}

TEST(TrajectoryMetrics, AlignTeamScoresEachRobotUnderTheJointAlignment) {
    // Robot 1 is 2 m above its truth: one transform for both leaves 1 m on each robot.
    const std::vector<Trajectory> gt = {Helix(30), Helix(30, 10.0)};
    Eigen::Isometry3d shift = Eigen::Isometry3d::Identity();
    shift.translation() = Eigen::Vector3d(0, 0, 2);
    const AlignedTeam team = AlignTeam(gt, {gt[0], Transformed(gt[1], shift)});
    ASSERT_EQ(team.ate_rmse.size(), 2u);
    EXPECT_NEAR(team.ate_rmse[0], 1.0, 1e-6);
    EXPECT_NEAR(team.ate_rmse[1], 1.0, 1e-6);
}

}  // namespace
}  // namespace certislam::slam
