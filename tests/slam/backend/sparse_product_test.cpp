// The register-blocked V A agrees with Eigen's product for every rank it specialises and the
// fallback, on compressed and uncompressed random matrices and on a real connection Laplacian.
#include "slam/backend/sparse_product.h"

#include <gtest/gtest.h>

#include <random>
#include <string>
#include <vector>

#include "slam/backend/connection_laplacian.h"
#include "slam/io/g2o_io.h"
#include "tests/data_paths.h"
#include "tests/slam/backend/random_dense.h"

namespace certislam::slam {
namespace {

constexpr double kRoundingRel = 1e-13;  ///< |difference| / |product|: summation order only

Eigen::SparseMatrix<double> RandomSparse(int rows, int cols, double density, unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> uniform(-1.0, 1.0);
    std::bernoulli_distribution keep(density);
    std::vector<Eigen::Triplet<double>> triplets;
    for (int j = 0; j < cols; ++j) {
        for (int i = 0; i < rows; ++i) {
            if (keep(rng)) triplets.emplace_back(i, j, uniform(rng));
        }
    }
    Eigen::SparseMatrix<double> A(rows, cols);
    A.setFromTriplets(triplets.begin(), triplets.end());
    return A;
}

using testing::RandomDense;

double RelativeError(const Eigen::MatrixXd& V, const Eigen::SparseMatrix<double>& A) {
    const Eigen::MatrixXd reference = V * A;
    const Eigen::MatrixXd mine = DenseTimesSparse(V, A);
    EXPECT_EQ(mine.rows(), reference.rows());
    EXPECT_EQ(mine.cols(), reference.cols());
    return (mine - reference).norm() / reference.norm();
}

TEST(SparseProduct, MatchesEigenForEveryRankOnCompressedMatrices) {
    const Eigen::SparseMatrix<double> A = RandomSparse(40, 35, 0.2, 1);
    ASSERT_TRUE(A.isCompressed());
    for (int r = 1; r <= 10; ++r) {  // 1-8 specialised, 9 and 10 the fallback
        EXPECT_LT(RelativeError(RandomDense(r, 40, 10 + r), A), kRoundingRel) << "r = " << r;
    }
}

TEST(SparseProduct, MatchesEigenOnUncompressedMatrices) {
    Eigen::SparseMatrix<double> A = RandomSparse(30, 30, 0.15, 2);
    A.reserve(Eigen::VectorXi::Constant(30, 12));  // leaves gaps between the columns
    A.coeffRef(3, 7) += 2.5;
    A.coeffRef(29, 0) -= 1.0;
    ASSERT_FALSE(A.isCompressed());
    for (int r : {2, 3, 5}) {
        EXPECT_LT(RelativeError(RandomDense(r, 30, 20 + r), A), kRoundingRel) << "r = " << r;
    }
}

TEST(SparseProduct, EmptyColumnsGiveZeroColumns) {
    Eigen::SparseMatrix<double> A(5, 4);
    A.insert(1, 2) = 3.0;
    A.makeCompressed();
    const Eigen::MatrixXd out = DenseTimesSparse(Eigen::MatrixXd::Ones(3, 5), A);
    EXPECT_EQ(out.col(0).norm(), 0.0);
    EXPECT_EQ(out.col(3).norm(), 0.0);
    EXPECT_EQ(out(2, 2), 3.0);
}

TEST(SparseProduct, MatchesEigenOnParkingGarageConnectionLaplacian) {
    const PoseGraphReadResult read = ReadG2o(test_data::G2oPath("parking-garage.g2o"));
    ASSERT_TRUE(read.ok()) << read.error;
    const Eigen::SparseMatrix<double> Q = ConnectionLaplacian(read.graph);
    for (int r : {3, 4}) {
        EXPECT_LT(RelativeError(RandomDense(r, static_cast<int>(Q.rows()), 30 + r), Q),
                  kRoundingRel)
            << "r = " << r;
    }
}

}  // namespace
}  // namespace certislam::slam
