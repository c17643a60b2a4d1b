// Tests of the dual certificate: closed-form optimum certifies, a twisted critical point does
// not, a non-critical point is refused, and the eigensolver matches a dense solver.
#include "certify/certificate.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <functional>
#include <random>
#include <string>

#include "certify/min_eigenpair.h"
#include "slam/backend/connection_laplacian.h"
#include "slam/backend/stiefel.h"
#include "slam/core/graph_split.h"
#include "tests/certify/test_graphs.h"

namespace certislam::certify {
namespace {

using testing::Edge;
using testing::Rot;

constexpr double kCostTolerance = 1e-10;       // relative, closed form vs f(X)
constexpr double kDenseMatchTolerance = 1e-8;  // relative to ||Q||
constexpr double kSaddleCurvature = 1e-3;      // relative; the twist's eigenvalue is far below

Eigen::MatrixXd ProjectToSO(const Eigen::MatrixXd& M) {
    Eigen::JacobiSVD<Eigen::MatrixXd> svd(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::MatrixXd D = Eigen::MatrixXd::Identity(M.rows(), M.cols());
    D(M.rows() - 1, M.rows() - 1) = (svd.matrixU() * svd.matrixV().transpose()).determinant();
    return svd.matrixU() * D * svd.matrixV().transpose();
}

/// Two poses joined by two disagreeing edges: R_2 = Proj_SO(k1 A + k2 B), t_2 = tau-weighted mean.
struct TwoPoseProblem {
    slam::PoseGraph graph;
    Eigen::MatrixXd X;
    double f_star = 0.0;
};

TwoPoseProblem MakeTwoPose(int d) {
    TwoPoseProblem p;
    p.graph.d = d;
    p.graph.n = 2;
    Eigen::VectorXd ta = Eigen::VectorXd::LinSpaced(d, 1.0, 2.0);
    Eigen::VectorXd tb = Eigen::VectorXd::LinSpaced(d, 1.5, 1.0);
    Eigen::MatrixXd A = Rot(d, 0.3), B = Rot(d, 0.5);
    if (d == 3) B = B * Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitX()).toRotationMatrix();
    p.graph.edges = {Edge(0, 1, A, ta, 2.0, 5.0), Edge(0, 1, B, tb, 3.0, 1.0)};
    const Eigen::MatrixXd R2 = ProjectToSO(2.0 * A + 3.0 * B);
    const Eigen::VectorXd t2 = (5.0 * ta + 1.0 * tb) / 6.0;
    p.X = Eigen::MatrixXd::Zero(d, 2 * (d + 1));
    p.X.block(0, 0, d, d).setIdentity();
    p.X.block(0, d + 1, d, d) = R2;
    p.X.col(2 * d + 1) = t2;
    p.f_star = 2.0 * (R2 - A).squaredNorm() + 3.0 * (R2 - B).squaredNorm() +
               5.0 * (t2 - ta).squaredNorm() + 1.0 * (t2 - tb).squaredNorm();
    return p;
}

class TwoPoseByDimension : public ::testing::TestWithParam<int> {};

TEST_P(TwoPoseByDimension, ClosedFormOptimumCertifies) {
    const int d = GetParam();
    const TwoPoseProblem p = MakeTwoPose(d);
    const auto Q = slam::ConnectionLaplacian(p.graph);
    const CertificateResult result = Certify(Q, p.X, d);
    EXPECT_EQ(result.status, CertificateResult::Status::kCertified);
    EXPECT_NEAR(result.objective, p.f_star, kCostTolerance * p.f_star);
    EXPECT_NEAR(result.duality_gap, 0.0, kCostTolerance * p.f_star);
    EXPECT_GE(result.lambda_min_relative, -kDenseMatchTolerance);
    EXPECT_LE(result.suboptimality_bound, result.eta * d * 2 + kCostTolerance * p.f_star);
    // The exact bound: f* >= lower_bound, and it is f* up to the refined eta d n.
    ASSERT_TRUE(result.has_bound);
    EXPECT_LE(result.lower_bound, p.f_star * (1.0 + kCostTolerance));
    EXPECT_GE(result.lower_bound, p.f_star * (1.0 - 1e-6));
    EXPECT_LE(result.relative_suboptimality_bound, 1e-6);
    EXPECT_STREQ(VerdictName(result.status), "certified");
}

TEST_P(TwoPoseByDimension, PerturbedPointIsNotCritical) {
    const int d = GetParam();
    TwoPoseProblem p = MakeTwoPose(d);
    p.X.block(0, d + 1, d, d) = p.X.block(0, d + 1, d, d) * Rot(d, 0.05);
    const CertificateResult result = Certify(slam::ConnectionLaplacian(p.graph), p.X, d);
    EXPECT_EQ(result.status, CertificateResult::Status::kNotCritical);
    EXPECT_GT(result.gradient_norm, result.gradient_tolerance);
    EXPECT_FALSE(result.has_bound);  // no bound at a point that is not critical
    EXPECT_EQ(result.lower_bound, 0.0);
    EXPECT_EQ(result.suboptimality_bound, 0.0);
}

TEST_P(TwoPoseByDimension, TwistedCycleIsCriticalButNotCertified) {
    const int d = GetParam();
    const int n = 8;
    const auto Q = slam::ConnectionLaplacian(testing::IdentityCycle(d, n));
    const CertificateResult result = Certify(Q, testing::TwistedCycle(d, n), d);
    EXPECT_EQ(result.status, CertificateResult::Status::kNotOptimal);
    EXPECT_GT(result.objective, 1.0);  // f* = 0
    EXPECT_LE(result.gradient_norm, result.gradient_tolerance);
    EXPECT_LT(result.lambda_min_relative, -kSaddleCurvature);
    EXPECT_FALSE(result.psd_at_eta);
    EXPECT_FALSE(result.has_bound);  // tr(Lambda) - eta d n is no bound here
    EXPECT_EQ(result.suboptimality_bound, 0.0);
    EXPECT_GT(result.escape_descent, 0.0);
    ASSERT_EQ(result.eigenvector.size(), Q.rows());
    EXPECT_NEAR(result.eigenvector.norm(), 1.0, 1e-12);
}

INSTANTIATE_TEST_SUITE_P(Dimensions, TwoPoseByDimension, ::testing::Values(2, 3),
                         [](const auto& info) { return "d" + std::to_string(info.param); });

double DenseLambdaMin(const Eigen::SparseMatrix<double>& S) {
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> dense{Eigen::MatrixXd(S)};
    return dense.eigenvalues()(0);
}

/// A random noisy 3D graph (chain + random loops) and a random point X on the manifold.
std::pair<Eigen::SparseMatrix<double>, Eigen::MatrixXd> RandomProblem(int n, int r, int seed) {
    std::mt19937 rng(seed);
    std::normal_distribution<double> normal;
    std::uniform_int_distribution<int> pick(0, n - 1);
    slam::PoseGraph graph;
    graph.n = n;
    auto random_rotation = [&] {
        return Eigen::MatrixXd(
            Eigen::Quaterniond(normal(rng), normal(rng), normal(rng), normal(rng))
                .normalized()
                .toRotationMatrix());
    };
    for (int k = 0; k < 3 * n; ++k) {
        const int i = k < n - 1 ? k : pick(rng);
        const int j = k < n - 1 ? k + 1 : pick(rng);
        if (i == j) continue;
        graph.edges.push_back(Edge(i, j, random_rotation(), Eigen::Vector3d::Random(),
                                   1.0 + std::abs(normal(rng)), 0.5 + std::abs(normal(rng))));
    }
    Eigen::MatrixXd X = Eigen::MatrixXd::Random(r, 4 * n);
    for (int i = 0; i < n; ++i) {
        Eigen::HouseholderQR<Eigen::MatrixXd> qr(X.middleCols(4 * i, 3));
        X.middleCols(4 * i, 3) = qr.householderQ() * Eigen::MatrixXd::Identity(r, 3);
    }
    return {slam::ConnectionLaplacian(graph), X};
}

TEST(SmallestEigenpair, MatchesDenseSolverOnCertificateMatrices) {
    for (int seed = 1; seed <= 4; ++seed) {
        const auto [Q, X] = RandomProblem(12, 4, seed);
        const auto S = CertificateMatrix(Q, LambdaBlocks(Q, X, 3), 3);
        const double scale = NormUpperBound(Q);
        const MinEigenpairResult pair = SmallestEigenpair(S);
        ASSERT_EQ(pair.status, MinEigenpairResult::Status::kConverged) << "seed " << seed;
        EXPECT_NEAR(pair.lambda, DenseLambdaMin(S), kDenseMatchTolerance * scale) << seed;
        EXPECT_LE(pair.residual, kDenseMatchTolerance * scale);
        const MinEigenpairResult on_q = SmallestEigenpair(Q);  // PSD with the gauge null vector
        ASSERT_EQ(on_q.status, MinEigenpairResult::Status::kConverged);
        EXPECT_NEAR(on_q.lambda, DenseLambdaMin(Q), kDenseMatchTolerance * scale);
    }
}

// A very sparse factor (tridiagonal: flops / nnz(L) about 1) is simplicial in CHOLMOD's choice;
// its shift search must still refuse indefinite shifts (an LDL^T would accept them and the
// Lanczos run would then converge to the wrong end of the spectrum).
TEST(SmallestEigenpair, FindsTheNegativeEndOfAKnownSpectrumWithASimplicialFactor) {
    const int n = 500;
    const double offset = 0.5;
    std::vector<Eigen::Triplet<double>> triplets;
    for (int i = 0; i < n; ++i) {
        triplets.emplace_back(i, i, 2.0 - offset);
        if (i + 1 < n) {
            triplets.emplace_back(i, i + 1, -1.0);
            triplets.emplace_back(i + 1, i, -1.0);
        }
    }
    Eigen::SparseMatrix<double> S(n, n);
    S.setFromTriplets(triplets.begin(), triplets.end());
    const double expected = 2.0 - 2.0 * std::cos(M_PI / (n + 1)) - offset;  // closed form
    const MinEigenpairResult pair = SmallestEigenpair(S);
    ASSERT_EQ(pair.status, MinEigenpairResult::Status::kConverged);
    const double scale = 4.0;  // ||S|| <= 4 (Gershgorin)
    EXPECT_NEAR(pair.lambda, expected, kDenseMatchTolerance * scale);
    EXPECT_LE(pair.residual, kDenseMatchTolerance * scale);
}

TEST(SmallestEigenpair, IsReproducibleWithFixedSeed) {
    const auto [Q, X] = RandomProblem(10, 3, 7);
    const auto S = CertificateMatrix(Q, LambdaBlocks(Q, X, 3), 3);
    EXPECT_EQ(SmallestEigenpair(S).lambda, SmallestEigenpair(S).lambda);
}

// The bound refinement's bisection: for every threshold of a monotone predicate it returns the
// last passing index, as a linear scan would, in at most ceil(log2(fail - pass)) calls.
TEST(LastPassing, FindsEveryThresholdInLogarithmicCalls) {
    for (int fail = 1; fail <= 9; ++fail) {
        const int max_calls = static_cast<int>(std::ceil(std::log2(fail)));
        for (int threshold = 0; threshold < fail; ++threshold) {
            int calls = 0;
            const int found = LastPassing(0, fail, [&](int k) {
                ++calls;
                EXPECT_GT(k, 0) << "ok(pass) is given, not asked";
                EXPECT_LT(k, fail) << "fail is excluded";
                return k <= threshold;
            });
            EXPECT_EQ(found, threshold) << "fail " << fail;
            EXPECT_LE(calls, max_calls) << "fail " << fail << " threshold " << threshold;
        }
    }
}

// The refinement rule before VerdictAndBound: the verdict at eta, then one test at the target,
// then eta / 10 steps while PSD (kept here as the reference the search must agree with).
BoundSearch SteppedLadder(double eta, double lambda_min, int refinements,
                          const std::function<bool(double)>& psd_at) {
    BoundSearch out;
    out.bound_eta = eta;
    out.psd_at_eta = psd_at(eta);
    if (!out.psd_at_eta || refinements == 0) return out;
    double floor = eta;
    for (int k = 0; k < refinements; ++k) floor *= 0.1;
    const double target = std::max(4.0 * std::max(-lambda_min, 0.0), floor);
    if (target < eta && psd_at(target)) {
        out.bound_eta = target;
        return out;
    }
    double e = eta;
    for (int k = 0; k < refinements; ++k) {
        e *= 0.1;
        if (e <= target || !psd_at(e)) break;
        out.bound_eta = e;
    }
    return out;
}

// Every monotone PSD threshold (between, on and off the ladder's rungs, above eta, at 0) and
// lambda_min from clearly positive to clearly negative: same verdict and bound as the stepped
// ladder, every reported eta tested PSD, and at most 3 + ceil(log2(refinements)) tests.
TEST(VerdictAndBound, AgreesWithTheSteppedLadderForEveryThreshold) {
    const double eta = 2.5e-4;
    for (int refinements : {0, 1, 2, 6}) {
        for (double exponent = -1.0; exponent <= 9.0; exponent += 0.25) {
            const double threshold = eta * std::pow(10.0, -exponent);
            const auto psd_at = [&](double e) { return e >= threshold; };
            for (double lambda_min : {1e-3 * eta, 0.0, -1e-12 * eta, -1e-6 * eta, -1e-3 * eta,
                                      -0.1 * eta, -eta, -3.0 * eta}) {
                const BoundSearch got = VerdictAndBound(eta, lambda_min, refinements, psd_at);
                const BoundSearch want = SteppedLadder(eta, lambda_min, refinements, psd_at);
                const std::string where = "refinements " + std::to_string(refinements) +
                                          " threshold " + std::to_string(threshold) +
                                          " lambda_min " + std::to_string(lambda_min);
                EXPECT_EQ(got.psd_at_eta, want.psd_at_eta) << where;
                if (!want.psd_at_eta) continue;
                EXPECT_EQ(got.bound_eta, want.bound_eta) << where;
                EXPECT_TRUE(psd_at(got.bound_eta)) << where;
                const int max_tests =
                    3 + static_cast<int>(std::ceil(std::log2(std::max(refinements, 1))));
                EXPECT_LE(got.factorizations, max_tests) << where;
            }
        }
    }
}

// On a certified optimum the refined eta really makes S + eta D PSD (dense check, D = identity
// on rotation entries) and is no larger than the verdict's eta.
TEST_P(TwoPoseByDimension, RefinedBoundEtaKeepsTheShiftedMatrixPsd) {
    const int d = GetParam();
    const TwoPoseProblem p = MakeTwoPose(d);
    const auto Q = slam::ConnectionLaplacian(p.graph);
    const CertificateResult result = Certify(Q, p.X, d);
    ASSERT_EQ(result.status, CertificateResult::Status::kCertified);
    EXPECT_LE(result.bound_eta, result.eta);
    Eigen::MatrixXd shifted = CertificateMatrix(Q, LambdaBlocks(Q, p.X, d), d);
    for (int i = 0; i < shifted.rows(); ++i) {
        if (i % (d + 1) != d) shifted(i, i) += result.bound_eta;
    }
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> dense(shifted);
    EXPECT_GE(dense.eigenvalues()(0), -kDenseMatchTolerance * result.q_norm);
}

/// Parallel edges merged (slam::MergeParallelEdges) change Q by the tau t t^T terms of the tails'
/// rotation blocks only, which Lambda(X) takes up: at any X on the manifold, S is the file's and
/// f(X) is the file's minus the merge's constant (what lets a split team certify the file).
TEST(Certificate, MergedParallelEdgesLeaveTheCertificateMatrixAsTheFilesIs) {
    Eigen::MatrixXd truth;
    slam::PoseGraph file = testing::NoisySphere(3, 6, 0.05, 0.1, 7, &truth);
    std::mt19937 rng(11);
    const size_t m = file.edges.size();
    for (size_t k = 0; k < m; k += 3) {  // a second, different measurement of every third edge
        slam::RelativePoseMeasurement e = file.edges[k];
        e.R = e.R * testing::RandomRotation(3, 0.2, rng);
        e.t += Eigen::Vector3d(0.3, -0.2, 0.1);
        e.kappa *= 0.5;
        e.tau *= 2.0;
        file.edges.push_back(e);
    }
    const slam::MergedGraph merged = slam::MergeParallelEdges(file);
    ASSERT_GT(merged.merged, 0);
    double offset = 0.0;
    for (const double c : merged.cost) offset += c;
    const int d = 3, r = 5;
    const Eigen::MatrixXd X = slam::ProjectToManifold(
        Eigen::MatrixXd::Random(r, (d + 1) * file.n) * 3.0, d);  // fixed seed: Eigen's rand
    const auto Q_file = slam::ConnectionLaplacian(file);
    const auto Q_merged = slam::ConnectionLaplacian(merged.graph);
    const Eigen::MatrixXd S_file =
        Eigen::MatrixXd(CertificateMatrix(Q_file, LambdaBlocks(Q_file, X, d), d));
    const Eigen::MatrixXd S_merged =
        Eigen::MatrixXd(CertificateMatrix(Q_merged, LambdaBlocks(Q_merged, X, d), d));
    EXPECT_GT((Eigen::MatrixXd(Q_file) - Eigen::MatrixXd(Q_merged)).norm(), 1.0);
    EXPECT_LE((S_file - S_merged).norm(), kDenseMatchTolerance * S_file.norm());
    const double f_file = (X * Q_file * X.transpose()).trace();
    const double f_merged = (X * Q_merged * X.transpose()).trace();
    EXPECT_GT(offset, 0.0);
    EXPECT_NEAR(f_file, f_merged + offset, kCostTolerance * f_file);
}

/// A chain of n poses starting at `start`, heavy weights, X composed from the measurements
/// (a tree: f* = 0); 10 km out, the Laplacian form cancels terms of 10^15 and more.
struct FarChain {
    slam::PoseGraph graph;
    Eigen::MatrixXd X;
};

FarChain MakeFarChain(int n, const Eigen::Vector3d& start) {
    FarChain c;
    c.graph.d = 3;
    c.graph.n = n;
    c.X = Eigen::MatrixXd::Zero(3, 4 * n);
    Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
    Eigen::Vector3d t = start;
    for (int k = 0; k < n; ++k) {
        c.X.block(0, 4 * k, 3, 3) = R;
        c.X.col(4 * k + 3) = t;
        const Eigen::Matrix3d dR = (Eigen::AngleAxisd(0.01 * k, Eigen::Vector3d::UnitZ()) *
                                    Eigen::AngleAxisd(0.002, Eigen::Vector3d::UnitX()))
                                       .toRotationMatrix();
        const Eigen::Vector3d dt(1.3, 0.1 * std::sin(k), 0.01);
        if (k + 1 < n) c.graph.edges.push_back(Edge(k, k + 1, dR, dt, 1e4, 1e5));
        t += R * dt;
        R = R * dR;
    }
    return c;
}

TEST(Objective, TreeComposedInDoublesIsWithinItsFloorFarBelowTheNormProduct) {
    const FarChain c = MakeFarChain(300, Eigen::Vector3d(1e4, -2e4, 30.0));
    const auto Q = slam::ConnectionLaplacian(c.graph);
    const ObjectiveShare f = ObjectiveOfColumns(Q, c.X, 0, Q.cols());
    EXPECT_GE(f.value, 0.0);
    EXPECT_LE(f.value, f.noise);
    // The floor weighs Q's rounding by |X|^T |Q| |X|, not a norm product (1e-12 ||Q|| ||X||^2
    // certified points that were not optimal).
    EXPECT_LT(f.noise, 1e-14 * NormUpperBound(Q) * c.X.squaredNorm());
}

TEST(Objective, OneCentimetreOffATreeCostsItsClosedFormAndEveryEdgesSum) {
    FarChain c = MakeFarChain(300, Eigen::Vector3d(3.0, -2.0, 1.0));
    const int k = 150;
    c.X(0, 4 * k + 3) += 1e-2;  // moves pose k: its two edges each cost tau (1e-2)^2
    const auto Q = slam::ConnectionLaplacian(c.graph);
    const ObjectiveShare f = ObjectiveOfColumns(Q, c.X, 0, Q.cols());
    const double expected = 2.0 * 1e5 * 1e-4;
    EXPECT_NEAR(f.value, expected, 1e-9 * expected);
    EXPECT_NEAR(f.value, slam::Objective(c.graph, c.X), 1e-9 * expected);
    EXPECT_GT(f.value, 10.0 * f.noise);
    // Split by columns, the shares add up to the whole (how the robots sum it).
    const ObjectiveShare a = ObjectiveOfColumns(Q, c.X, 0, 4 * k);
    const ObjectiveShare b = ObjectiveOfColumns(Q, c.X, 4 * k, Q.cols());
    EXPECT_NEAR(a.value + b.value, f.value, 1e-12 * expected);
}

/// The quantities of a 3D problem of n poses with f(X), tr(Lambda), ||Q|| and ||X|| (no rounding
/// noise to speak of).
CertificateQuantities Quantities3D(int n, double objective, double dual_value, double q_norm,
                                   double x_norm) {
    CertificateQuantities q;
    q.d = 3;
    q.n = n;
    q.objective = objective;
    q.dual_value = dual_value;
    q.q_norm = q_norm;
    q.x_norm = x_norm;
    q.objective_noise = 1e-20;
    return q;
}

TEST(Certificate, ALooseBoundAtASmallCostIsNotCertified) {
    // f(X) = 0.237 with tr(Lambda) = 0.2 and ||Q|| ||X||^2 1e-12 = 0.25: the old norm-product
    // floor called this "certified within rounding noise"; its proven bound is 16 % of f.
    const CertificateQuantities q = Quantities3D(40, 0.237, 0.2, 1e4, 5e3);
    CertificateConfig config;
    CertificateResult result;
    ASSERT_TRUE(FirstOrderVerdict(q, config, &result));
    SecondOrderVerdict(
        q, 1e-9, config, [](double) { return true; }, &result);
    ASSERT_TRUE(result.has_bound);
    EXPECT_GT(result.relative_suboptimality_bound, 0.1);
    EXPECT_STREQ(VerdictName(result.status), "inconclusive");
}

TEST(Certificate, AnEtaBetweenTheLaddersRungsCertifies) {
    // eta = 1e-7 ||Q|| = 0.1; S + e D factorizes from e = 5e-7 on. The rung 1e-7 fails, 1e-6
    // passes but bounds f - f* by 1e-6 d n = 3e-4, 1.2e-6 of f; 7.5e-7 (0.9 of the allowance)
    // factorizes and bounds it by 9e-7 of f.
    const CertificateQuantities q = Quantities3D(100, 250.0, 250.0, 1e6, 1.0);
    CertificateConfig config;
    CertificateResult result;
    ASSERT_TRUE(FirstOrderVerdict(q, config, &result));
    SecondOrderVerdict(
        q, -1e-8, config, [](double e) { return e >= 5e-7; }, &result);
    ASSERT_TRUE(result.has_bound);
    EXPECT_NEAR(result.bound_eta, 7.5e-7, 1e-12);
    EXPECT_LE(result.relative_suboptimality_bound, config.max_relative_bound);
    EXPECT_STREQ(VerdictName(result.status), "certified");
}

TEST(CertificateConfig, RejectsBadValuesNamingTheField) {
    CertificateConfig config;
    config.eta_relative = -1.0;
    try {
        config.Validate();
        FAIL() << "no exception";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("eta_relative"), std::string::npos);
    }
}

}  // namespace
}  // namespace certislam::certify
