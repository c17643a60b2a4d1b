// The small Rayleigh-Ritz problem of one LOBPCG iteration, solved from the reduced Gram matrices
// alone, so every robot that holds the same sums computes the same coefficients.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <vector>

namespace certislam::certify {

/// The basis Z = [X W P] of one LOBPCG iteration, by its reduced Gram matrices.
struct LobpcgGram {
    Eigen::MatrixXd gram;    ///< Z^T Z (s x s, s = x + w + p)
    Eigen::MatrixXd s_gram;  ///< Z^T S Z
    int x = 0;               ///< columns of X (first)
    int w = 0;               ///< columns of W (next)
    int p = 0;               ///< columns of P (last)
};

/// Coefficients of the new iterate in Z: X_new = Z coefficients (s x wanted).
struct RayleighRitzResult {
    bool ok = false;               ///< false: fewer than `wanted` independent directions
    Eigen::VectorXd ritz_values;   ///< ascending, `wanted` of them
    Eigen::MatrixXd coefficients;  ///< s x wanted, Z-orthonormal columns
    bool dropped_p = false;        ///< P was left out (the basis was too ill-conditioned)
    int dropped_directions = 0;    ///< directions of [X W] truncated as linearly dependent
};

/// Rayleigh-Ritz on span(Z) for the `wanted` smallest Ritz pairs. The basis is orthonormalised
/// through its Gram matrix (columns scaled to unit norm, then the eigenvectors of the scaled Gram
/// matrix whose eigenvalues exceed drop_tolerance times the largest, as in SVQB). If any direction
/// falls below that, P is dropped and the problem solved on [X W] (Duersch et al. 2018's restart:
/// the basis [X W P] loses independence as the iteration converges).
RayleighRitzResult SolveRayleighRitz(const LobpcgGram& z, int wanted, double drop_tolerance);

/// Appends the upper triangle of M (row by row) to `out` (a symmetric sum over robots needs only
/// the sum of the partial upper triangles).
void PackUpper(const Eigen::MatrixXd& M, std::vector<double>* out);

/// The symmetric s x s matrix packed by PackUpper from `in` at `*from` (advanced past it).
Eigen::MatrixXd UnpackUpper(const std::vector<double>& in, Eigen::Index s, size_t* from);

}  // namespace certislam::certify
