// Keyframe selection by travelled distance and rotation (LIO-SAM defaults 1 m / 0.2 rad).
#include "slam/core/keyframe_selection.h"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

namespace certislam::slam {
namespace {

Eigen::Isometry3d Pose(double x, double yaw) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    T.translation() = Eigen::Vector3d(x, 0, 0);
    return T;
}

TEST(KeyframeSelection, StraightDriveGivesOneKeyframePerMetre) {
    std::vector<Eigen::Isometry3d> poses;
    for (int i = 0; i <= 100; ++i) poses.push_back(Pose(0.1 * i, 0.0));  // 10 m at 0.1 m steps
    const auto kf = SelectKeyframes(poses);
    ASSERT_EQ(kf.size(), 11u);
    for (size_t k = 0; k < kf.size(); ++k) EXPECT_EQ(kf[k], static_cast<int>(10 * k));
}

TEST(KeyframeSelection, TurningInPlaceSelectsByRotation) {
    std::vector<Eigen::Isometry3d> poses;
    for (int i = 0; i <= 40; ++i) poses.push_back(Pose(0.0, 0.06 * i));  // 0.06 rad steps
    const auto kf = SelectKeyframes(poses);
    ASSERT_EQ(kf.size(), 11u);  // 0.24 rad (4 steps) passes 0.2, 0.18 does not
    EXPECT_EQ(kf[1], 4);
}

TEST(KeyframeSelection, SmallMotionsAccumulateAgainstTheLastKeyframe) {
    KeyframeSelector sel;
    EXPECT_TRUE(sel.Accept(Pose(0.0, 0.0)));
    EXPECT_FALSE(sel.Accept(Pose(0.6, 0.1)));
    EXPECT_FALSE(sel.Accept(Pose(0.99, 0.19)));
    EXPECT_TRUE(sel.Accept(Pose(1.01, 0.0)));
    EXPECT_FALSE(sel.Accept(Pose(1.5, 0.0)));
    sel.Reset();
    EXPECT_TRUE(sel.Accept(Pose(1.5, 0.0)));
}

TEST(KeyframeSelection, ValidateRejectsNegativeThresholds) {
    KeyframeSelectionConfig cfg;
    cfg.min_rotation_rad = -1.0;
    try {
        KeyframeSelector sel(cfg);
        ADD_FAILURE() << "no exception";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("min_rotation_rad"), std::string::npos);
    }
}

}  // namespace
}  // namespace certislam::slam
