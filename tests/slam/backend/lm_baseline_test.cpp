// Tests of the Levenberg-Marquardt baseline: exact objective, noise-free recovery, real files.
#include "slam/backend/lm_baseline.h"

#include <ceres/gradient_checker.h>
#include <ceres/manifold.h>
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cstdlib>
#include <vector>

#include "slam/backend/chordal.h"
#include "slam/backend/connection_laplacian.h"
#include "slam/backend/lm_se3_edge_cost.h"
#include "slam/io/g2o_io.h"
#include "tests/certify/test_graphs.h"
#include "tests/data_paths.h"

namespace certislam::slam {
namespace {

constexpr double kRelativeGap = 1e-6;
constexpr double kNoiseFreeCost = 1e-12;

// The analytic Jacobians of the 3D edge agree with Ceres' numerical differentiation (on the
// quaternion manifold and in ambient coordinates) at random poses and measurements.
TEST(LmBaseline, Se3EdgeJacobiansMatchNumericalDifferentiation) {
    std::srand(7);
    for (int trial = 0; trial < 20; ++trial) {
        const Eigen::Matrix3d R = Eigen::Quaterniond::UnitRandom().toRotationMatrix();
        const Eigen::Vector3d t = Eigen::Vector3d::Random() * 5.0;
        const Se3EdgeCost cost(R, t, 1.7, 0.3);
        Eigen::Quaterniond qi = Eigen::Quaterniond::UnitRandom(),
                           qj = Eigen::Quaterniond::UnitRandom();
        Eigen::Vector3d ti = Eigen::Vector3d::Random() * 10.0,
                        tj = Eigen::Vector3d::Random() * 10.0;
        const double* parameters[] = {qi.coeffs().data(), ti.data(), qj.coeffs().data(), tj.data()};
        ceres::EigenQuaternionManifold quaternion;
        const std::vector<const ceres::Manifold*> manifolds = {&quaternion, nullptr, &quaternion,
                                                               nullptr};
        const ceres::GradientChecker checker(&cost, &manifolds, ceres::NumericDiffOptions());
        ceres::GradientChecker::ProbeResults results;
        checker.Probe(parameters, 1e-7, &results);  // its relative test fails on zeros: below
        ASSERT_EQ(results.jacobians.size(), 4u);
        for (size_t b = 0; b < 4; ++b) {
            const double error =
                (results.jacobians[b] - results.numeric_jacobians[b]).cwiseAbs().maxCoeff();
            EXPECT_LT(error, 1e-6 * (1.0 + results.numeric_jacobians[b].cwiseAbs().maxCoeff()))
                << "block " << b;
            EXPECT_LT((results.local_jacobians[b] - results.local_numeric_jacobians[b])
                          .cwiseAbs()
                          .maxCoeff(),
                      1e-6 * (1.0 + results.local_numeric_jacobians[b].cwiseAbs().maxCoeff()))
                << "block " << b;
        }
        // The residual: sqrt(kappa) vec(R_j - R_i R~) and sqrt(tau) (t_j - t_i - R_i t~).
        const Eigen::Matrix3d Ri = qi.toRotationMatrix(), Rj = qj.toRotationMatrix();
        const Eigen::Matrix3d E = Rj - Ri * R;
        const Eigen::Vector3d e = tj - ti - Ri * t;
        for (int k = 0; k < 9; ++k) EXPECT_NEAR(results.residuals[k], 1.7 * E(k % 3, k / 3), 1e-12);
        for (int k = 0; k < 3; ++k) EXPECT_NEAR(results.residuals[9 + k], 0.3 * e[k], 1e-12);
    }
}

TEST(LmBaseline, RecoversNoiseFreeSphereFromOdometry) {
    Eigen::MatrixXd truth;
    PoseGraph graph = certify::testing::NoisySphere(4, 8, 0.1, 0.1, 5, &truth);
    // Replace the measurements by exact ones: f* = 0 at the truth.
    for (auto& e : graph.edges) {
        const Eigen::Matrix3d Ri = truth.block(0, 4 * e.i, 3, 3);
        e.R = Ri.transpose() * truth.block(0, 4 * e.j, 3, 3);
        e.t = Ri.transpose() * (truth.col(4 * e.j + 3) - truth.col(4 * e.i + 3));
    }
    const LmResult result = SolveLm(graph, OdometryInitialization(graph));
    EXPECT_EQ(result.status, LmResult::Status::kConverged);
    EXPECT_LT(result.cost, kNoiseFreeCost);
}

TEST(LmBaseline, CostIsTheSeSyncObjectiveOfItsPoses) {
    Eigen::MatrixXd truth;
    const PoseGraph graph = certify::testing::NoisySphere(4, 8, 0.05, 0.05, 6, &truth);
    const LmResult result = SolveLm(graph, OdometryInitialization(graph));
    EXPECT_DOUBLE_EQ(result.cost, Objective(graph, result.poses));
    EXPECT_GT(result.iterations, 0);
    EXPECT_LT(result.cost, result.initial_cost);
}

struct RealFile {
    const char* name;
    double f_star;  // data/g2o/README.md
};

class LmRealData : public ::testing::TestWithParam<RealFile> {};

TEST_P(LmRealData, FromOdometryReachesPublishedOptimum) {
    const auto read = ReadG2o(test_data::G2oPath(GetParam().name));
    ASSERT_TRUE(read.ok()) << read.error;
    const LmResult result = SolveLm(read.graph, OdometryInitialization(read.graph));
    EXPECT_EQ(result.status, LmResult::Status::kConverged) << result.message;
    // tinyGrid3D's listed f* is 1.2e-6 above the certified optimum (see staircase_test).
    EXPECT_LE(result.cost, GetParam().f_star * (1.0 + kRelativeGap));
}

INSTANTIATE_TEST_SUITE_P(Files, LmRealData,
                         ::testing::Values(RealFile{"tinyGrid3D.g2o", 18.5193868731},
                                           RealFile{"smallGrid3D.g2o", 1025.39802075},
                                           RealFile{"CSAIL.g2o", 31.7037159922}),
                         [](const auto& info) {
                             const std::string name = info.param.name;
                             return name.substr(0, name.find('.'));
                         });

TEST(LmConfig, RejectsBadValuesNamingTheField) {
    LmConfig config;
    config.max_iterations = 0;
    EXPECT_THROW(config.Validate(), std::invalid_argument);
    try {
        config.Validate();
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("max_iterations"), std::string::npos);
    }
}

}  // namespace
}  // namespace certislam::slam
