// The per-pose manifold operations against a direct per-pose Eigen reference, for d = 2 and 3
// and several ranks: the tangent projection (tangent, idempotent, translations kept) and the
// Weingarten term.
#include "slam/backend/stiefel.h"

#include <gtest/gtest.h>

#include <Eigen/QR>
#include <string>

#include "tests/slam/backend/random_dense.h"

namespace certislam::slam {
namespace {

constexpr double kRounding = 1e-12;  ///< absolute, on entries of order 1

using testing::RandomDense;

// A point of (St(d, r) x R^r)^k with exactly orthonormal rotation blocks (thin QR factors).
Eigen::MatrixXd RandomPoint(int d, int r, int k, unsigned seed) {
    Eigen::MatrixXd X = RandomDense(r, (d + 1) * k, seed);
    for (int g = 0; g < k; ++g) {
        const int c = g * (d + 1);
        const Eigen::HouseholderQR<Eigen::MatrixXd> qr(X.middleCols(c, d));
        X.middleCols(c, d) = qr.householderQ() * Eigen::MatrixXd::Identity(r, d);
    }
    return X;
}

Eigen::MatrixXd Sym(const Eigen::MatrixXd& S) { return 0.5 * (S + S.transpose()); }

struct Shape {
    int d;
    int r;
};

class StiefelOps : public ::testing::TestWithParam<Shape> {};

TEST_P(StiefelOps, ProjectionMatchesThePerPoseFormulaAndIsTangent) {
    const auto [d, r] = GetParam();
    const int k = 7;
    const Eigen::MatrixXd X = RandomPoint(d, r, k, 1);
    const Eigen::MatrixXd V = RandomDense(r, (d + 1) * k, 2);
    const Eigen::MatrixXd P = ProjectToTangent(X, V, d);
    for (int g = 0; g < k; ++g) {
        const int c = g * (d + 1);
        const Eigen::MatrixXd Y = X.middleCols(c, d);
        EXPECT_LT((Y.transpose() * Y - Eigen::MatrixXd::Identity(d, d)).norm(), kRounding);
        const Eigen::MatrixXd expected =
            V.middleCols(c, d) - Y * Sym(Y.transpose() * V.middleCols(c, d));
        EXPECT_LT((P.middleCols(c, d) - expected).norm(), kRounding) << "pose " << g;
        EXPECT_LT(Sym(Y.transpose() * P.middleCols(c, d)).norm(), kRounding) << "pose " << g;
        EXPECT_EQ(P.col(c + d), V.col(c + d)) << "translation of pose " << g;
    }
    EXPECT_LT((ProjectToTangent(X, P, d) - P).norm(), kRounding);
}

TEST_P(StiefelOps, WeingartenTermMatchesThePerPoseFormula) {
    const auto [d, r] = GetParam();
    const int k = 5;
    const Eigen::MatrixXd X = RandomPoint(d, r, k, 3);
    const Eigen::MatrixXd G = RandomDense(r, (d + 1) * k, 4);
    const Eigen::MatrixXd V = RandomDense(r, (d + 1) * k, 5);
    const Eigen::MatrixXd W = WeingartenTerm(X, G, V, d);
    for (int g = 0; g < k; ++g) {
        const int c = g * (d + 1);
        const Eigen::MatrixXd expected =
            V.middleCols(c, d) * Sym(X.middleCols(c, d).transpose() * G.middleCols(c, d));
        EXPECT_LT((W.middleCols(c, d) - expected).norm(), kRounding) << "pose " << g;
        EXPECT_EQ(W.col(c + d).norm(), 0.0) << "translation of pose " << g;
    }
}

INSTANTIATE_TEST_SUITE_P(Shapes, StiefelOps,
                         ::testing::Values(Shape{2, 2}, Shape{2, 3}, Shape{3, 3}, Shape{3, 4},
                                           Shape{3, 6}),
                         [](const ::testing::TestParamInfo<Shape>& info) {
                             return "d" + std::to_string(info.param.d) + "_r" +
                                    std::to_string(info.param.r);
                         });

}  // namespace
}  // namespace certislam::slam
