// Ray casting against analytic primitives, and the grid traversal against brute force.
#include "slam/sim/sim_world.h"
#include "slam/sim/sim_city.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>

namespace certislam::slam {
namespace {

constexpr double kExact = 1e-9;

SimWorld OneBox() {
    SimBox box{Eigen::Vector3d(10, -5, 0), Eigen::Vector3d(12, 5, 10)};
    return SimWorld({box}, {}, {}, true, 4.0);
}

TEST(SimWorld, RayHitsGroundPlaneAtAnalyticDistance) {
    const SimWorld world({}, {}, {}, true);
    const Eigen::Vector3d d = Eigen::Vector3d(1, 0, -1).normalized();
    const auto hit = world.CastRay(Eigen::Vector3d(0, 0, 2), d, 0.0, 100.0);
    ASSERT_TRUE(hit);
    EXPECT_NEAR(hit->t, 2.0 * std::sqrt(2.0), kExact);
    EXPECT_FALSE(world.CastRay(Eigen::Vector3d(0, 0, 2), Eigen::Vector3d(0, 0, 1), 0.0, 100.0));
    EXPECT_FALSE(world.CastRay(Eigen::Vector3d(0, 0, 2), d, 0.0, 2.0));  // beyond max range
}

TEST(SimWorld, RayHitsBoxFaceAtAnalyticDistance) {
    const SimWorld world = OneBox();
    const Eigen::Vector3d o(0, 0, 1.5);
    for (double deg : {0.0, 10.0, -20.0, 25.0}) {
        const double a = deg * M_PI / 180.0;
        const auto hit = world.CastRay(o, Eigen::Vector3d(std::cos(a), std::sin(a), 0), 0.0, 80);
        ASSERT_TRUE(hit) << deg;
        EXPECT_NEAR(hit->t, 10.0 / std::cos(a), kExact) << deg;
    }
    EXPECT_FALSE(world.CastRay(o, Eigen::Vector3d(-1, 0, 0), 0.0, 80.0));
    // Over the roof: the ray rises above z = 10 before x = 10.
    const Eigen::Vector3d up = Eigen::Vector3d(1, 0, 1).normalized();
    EXPECT_FALSE(world.CastRay(o, up, 0.0, 80.0));
}

TEST(SimWorld, RayHitsTrunkAndCrownAtAnalyticDistance) {
    const SimCylinder trunk{Eigen::Vector2d(5, 0), 0.5, 0.0, 3.0};
    const SimEllipsoid crown{Eigen::Vector3d(0, 0, 10), 2.0, 3.0};
    const SimWorld world({}, {trunk}, {crown}, false);
    const auto t = world.CastRay(Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(1, 0, 0), 0.0, 80);
    ASSERT_TRUE(t);
    EXPECT_NEAR(t->t, 4.5, kExact);
    const auto c = world.CastRay(Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(0, 0, 1), 0.0, 80);
    ASSERT_TRUE(c);
    EXPECT_NEAR(c->t, 6.0, kExact);  // crown bottom at z = 10 - 3
    // Above the trunk's top: misses.
    EXPECT_FALSE(world.CastRay(Eigen::Vector3d(0, 0, 3.5), Eigen::Vector3d(1, 0, 0), 0.0, 80));
}

TEST(SimWorld, GridTraversalEqualsBruteForceInTheGeneratedCity) {
    const GeneratedWorld gen = GenerateWorld(SimWorldConfig{}, 3);
    const SimWorld& fast = gen.world;
    ASSERT_GT(fast.boxes().size(), 50u);
    ASSERT_GT(fast.cylinders().size(), 50u);
    // One huge cell: every primitive is tested for every ray.
    const SimWorld brute(fast.boxes(), fast.cylinders(), fast.ellipsoids(), true, 1e5);
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    int hits = 0;
    for (int k = 0; k < 4000; ++k) {
        const Eigen::Vector3d o(60 + 60 * u(rng), 40 + 40 * u(rng), 1.8);
        const Eigen::Vector3d d = Eigen::Vector3d(u(rng), u(rng), 0.4 * u(rng)).normalized();
        const auto a = fast.CastRay(o, d, 1.0, 90.0);
        const auto b = brute.CastRay(o, d, 1.0, 90.0);
        ASSERT_EQ(a.has_value(), b.has_value()) << k;
        if (a) {
            EXPECT_NEAR(a->t, b->t, kExact) << k;
            ++hits;
        }
    }
    EXPECT_GT(hits, 2000);
}

TEST(SimWorld, SameSeedSameWorldDifferentSeedDifferentWorld) {
    const auto a = GenerateWorld(SimWorldConfig{}, 5);
    const auto b = GenerateWorld(SimWorldConfig{}, 5);
    const auto c = GenerateWorld(SimWorldConfig{}, 6);
    ASSERT_EQ(a.world.boxes().size(), b.world.boxes().size());
    for (size_t i = 0; i < a.world.boxes().size(); ++i) {
        EXPECT_EQ(a.world.boxes()[i].max, b.world.boxes()[i].max);
    }
    bool differs = a.world.boxes().size() != c.world.boxes().size();
    for (size_t i = 0; !differs && i < a.world.boxes().size(); ++i) {
        differs = a.world.boxes()[i].max != c.world.boxes()[i].max;
    }
    EXPECT_TRUE(differs);
}

TEST(SimWorld, ValidateNamesTheField) {
    SimWorldConfig cfg;
    cfg.block_pitch_m = 10.0;
    try {
        cfg.Validate();
        FAIL() << "no exception";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("block_pitch_m"), std::string::npos) << e.what();
    }
}

}  // namespace
}  // namespace certislam::slam
