// The "must show": LM from a bad guess on a noisy synthetic sphere stops at a suboptimal
// stationary point; the certificate says "not certified" there, and the staircase started from
// that point reaches the same f* as the certified solve from a chordal start.
#include <gtest/gtest.h>

#include "certify/staircase.h"
#include "slam/backend/chordal.h"
#include "slam/backend/connection_laplacian.h"
#include "slam/backend/lm_baseline.h"
#include "tests/certify/test_graphs.h"

namespace certislam::certify {
namespace {

constexpr double kRelativeGap = 1e-6;
constexpr double kSigmaRad = 0.1;  // rotation noise per measurement
constexpr double kSigmaM = 0.1;    // translation noise per measurement
constexpr int kRings = 8, kPerRing = 16;

struct Case {
    slam::PoseGraph graph;
    StaircaseResult good;  // certified optimum from the chordal start
    slam::LmResult lm;     // LM from random rotations
};

Case Solve(unsigned seed) {
    Case c;
    Eigen::MatrixXd truth;
    c.graph = testing::NoisySphere(kRings, kPerRing, kSigmaRad, kSigmaM, seed, &truth);
    const auto partition = slam::ContiguousPartition(c.graph.n, 1);
    c.good = SolveCertified(c.graph, partition,
                            slam::LiftToRank(slam::ChordalInitialization(c.graph), 5));
    c.lm = slam::SolveLm(c.graph, testing::RandomPoses(3, c.graph.n, seed + 100));
    return c;
}

TEST(LocalMinimum, LmFromBadGuessIsNotCertifiedAndStaircaseReachesOptimum) {
    const Case c = Solve(1);  // seed 1: LM stops about 10x above f* (seed scan: 1, 2, 6 do)
    ASSERT_EQ(c.good.status, StaircaseResult::Status::kCertified);
    const double f_star = c.good.certificate.objective;
    ASSERT_EQ(c.lm.status, slam::LmResult::Status::kConverged);
    EXPECT_GT(c.lm.cost, 2.0 * f_star);  // a genuinely worse stationary point

    // At rank d the LM poses are a point of the relaxation: critical, but not certified.
    const auto Q = slam::ConnectionLaplacian(c.graph);
    const CertificateResult at_lm = Certify(Q, c.lm.poses, 3);
    EXPECT_EQ(at_lm.status, CertificateResult::Status::kNotOptimal);
    EXPECT_LE(at_lm.gradient_norm, at_lm.gradient_tolerance);
    EXPECT_LT(at_lm.lambda_min, -at_lm.eta);

    const StaircaseResult escaped =
        SolveCertified(c.graph, slam::ContiguousPartition(c.graph.n, 1), c.lm.poses);
    ASSERT_EQ(escaped.status, StaircaseResult::Status::kCertified);
    EXPECT_GE(escaped.escapes, 1);
    EXPECT_NEAR(escaped.certificate.objective, f_star, kRelativeGap * f_star);
}

TEST(LocalMinimum, LmThatFindsTheOptimumIsCertified) {
    const Case c = Solve(3);  // seed 3: LM from random rotations reaches f*
    ASSERT_EQ(c.good.status, StaircaseResult::Status::kCertified);
    const double f_star = c.good.certificate.objective;
    EXPECT_NEAR(c.lm.cost, f_star, kRelativeGap * f_star);
    const CertificateResult at_lm = Certify(slam::ConnectionLaplacian(c.graph), c.lm.poses, 3);
    EXPECT_EQ(at_lm.status, CertificateResult::Status::kCertified);
}

}  // namespace
}  // namespace certislam::certify
