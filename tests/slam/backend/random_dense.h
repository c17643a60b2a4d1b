// A dense matrix of standard normal entries from a fixed seed, for the kernel tests.
#pragma once

#include <Eigen/Core>
#include <random>

namespace certislam::slam::testing {

/// rows x cols, entries N(0, 1) drawn in storage order from std::mt19937(seed).
inline Eigen::MatrixXd RandomDense(int rows, int cols, unsigned seed) {
    std::mt19937 rng(seed);
    std::normal_distribution<double> normal(0.0, 1.0);
    Eigen::MatrixXd V(rows, cols);
    for (Eigen::Index i = 0; i < V.size(); ++i) V.data()[i] = normal(rng);
    return V;
}

}  // namespace certislam::slam::testing
