// FuseKeyframes: two robots scanning one box scene from known poses give one consistent mesh.
#include "slam/mapping/keyframe_fusion.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <memory>

#include "tests/slam/mapping/tsdf_test_scenes.h"

namespace certislam::slam {
namespace {

constexpr double kVoxel = 0.2;

Keyframe Scan(const std::vector<testing::Box>& scene, const Eigen::Isometry3d& T_world_sensor) {
    Keyframe kf;
    kf.cloud = std::make_shared<PointCloud>(testing::ScanBoxes(scene, T_world_sensor, 16, 360));
    return kf;
}

TEST(KeyframeFusion, MeshOfTwoRobotsLiesOnTheScannedSurfaces) {
    const auto scene = testing::GroundAndCube();
    const Eigen::Isometry3d A = testing::Pose(0, 0, 0, 0.0), B = testing::Pose(10, 2, 0, 2.5);
    const std::vector<std::vector<Keyframe>> robots = {{Scan(scene, A)}, {Scan(scene, B)}};
    const std::vector<Trajectory> poses = {Trajectory{StampedPose{0.0, A}},
                                           Trajectory{StampedPose{0.0, B}}};
    std::vector<double> fractions;
    const TriangleMesh mesh =
        FuseKeyframes(robots, poses, kVoxel, [&](double f) { fractions.push_back(f); });
    ASSERT_GT(mesh.triangles.size(), 100u);
    for (const auto& v : mesh.vertices) {
        const Eigen::Vector3d p = v.cast<double>();
        ASSERT_LT(std::min(testing::DistanceToBoxSurface(scene[0], p),
                           testing::DistanceToBoxSurface(scene[1], p)),
                  kVoxel)
            << p.transpose();
    }
    EXPECT_EQ(fractions, (std::vector<double>{0.5, 1.0}));
}

TEST(KeyframeFusion, KeyframesWithoutAPoseAreSkipped) {
    const auto scene = testing::GroundAndCube();
    const Eigen::Isometry3d A = testing::Pose(0, 0, 0, 0.0);
    const std::vector<std::vector<Keyframe>> robots = {{Scan(scene, A)}, {Scan(scene, A)}};
    const Trajectory at_A{StampedPose{0.0, A}};
    const TriangleMesh one = FuseKeyframes({robots[0]}, {at_A}, kVoxel);
    const TriangleMesh skipped = FuseKeyframes(robots, {at_A, Trajectory{}}, kVoxel);
    EXPECT_EQ(one.vertices.size(), skipped.vertices.size());
    EXPECT_EQ(one.triangles.size(), skipped.triangles.size());
}

}  // namespace
}  // namespace certislam::slam
