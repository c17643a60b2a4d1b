// The smallest eigenpair of a sparse symmetric matrix by shift-invert Lanczos (Spectra + CHOLMOD).
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <cstdint>

namespace certislam::certify {

/// Settings of SmallestEigenpair.
struct MinEigenpairConfig {
    /// First shift tried: sigma = -initial_shift (> 0). sigma is multiplied by shift_growth
    /// until S - sigma I factorizes (then sigma < lambda_min(S) <= sigma / shift_growth).
    double initial_shift = 1e-6;
    double shift_growth = 4.0;      ///< > 1
    int max_shift_attempts = 60;    ///< > 0
    double tolerance = 1e-12;       ///< Spectra residual tolerance relative to the Ritz value
    int max_iterations = 1000;      ///< Lanczos restarts, > 0
    int subspace = 24;              ///< Lanczos basis size, >= 3
    std::uint64_t seed = 20261121;  ///< seed of the start vector

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// The result: lambda is the Rayleigh quotient of v (an upper bound of lambda_min(S)).
struct MinEigenpairResult {
    enum class Status { kConverged, kNoShiftFound, kNotConverged };
    Status status = Status::kNotConverged;
    double lambda = 0.0;     ///< v^T S v
    Eigen::VectorXd vector;  ///< unit eigenvector
    double residual = 0.0;   ///< ||S v - lambda v||
    double shift = 0.0;      ///< the sigma whose inverse was iterated on
    int iterations = 0;      ///< Lanczos restarts
    int shift_attempts = 0;  ///< factorizations tried
};

/// Smallest eigenpair of symmetric S (full storage): Lanczos on (S - sigma I)^{-1} with sigma
/// just below lambda_min, found by Cholesky attempts. Shift-invert makes the wanted eigenvalue
/// dominant and well separated, so a tight tolerance converges in few iterations even where
/// lambda_min sits in a cluster near 0 (which plain Lanczos on sigma I - S resolves slowly).
MinEigenpairResult SmallestEigenpair(const Eigen::SparseMatrix<double>& S,
                                     const MinEigenpairConfig& config = {});

}  // namespace certislam::certify
