// Rayleigh-Ritz from Gram matrices with truncation of dependent directions.
#include "certify/distributed/lobpcg_rayleigh_ritz.h"

#include <Eigen/Dense>
#include <cmath>
#include <vector>

namespace certislam::certify {
namespace {

/// Rayleigh-Ritz on the columns `keep` of Z; false when fewer than `wanted` directions survive.
bool SolveOn(const LobpcgGram& z, const std::vector<int>& keep, int wanted, double drop_tolerance,
             RayleighRitzResult* out) {
    const int k = static_cast<int>(keep.size());
    Eigen::MatrixXd G(k, k), H(k, k);
    Eigen::VectorXd scale(k);
    for (int i = 0; i < k; ++i) {
        const double g = z.gram(keep[i], keep[i]);
        if (!(g > 0.0)) return false;
        scale(i) = 1.0 / std::sqrt(g);
    }
    for (int i = 0; i < k; ++i) {
        for (int j = 0; j < k; ++j) {
            G(i, j) = scale(i) * scale(j) * z.gram(keep[i], keep[j]);
            H(i, j) = scale(i) * scale(j) * 0.5 *
                      (z.s_gram(keep[i], keep[j]) + z.s_gram(keep[j], keep[i]));
        }
    }
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> gram(G);
    if (gram.info() != Eigen::Success) return false;
    const Eigen::VectorXd& mu = gram.eigenvalues();  // ascending
    const double floor = drop_tolerance * mu(k - 1);
    int first = 0;
    while (first < k && !(mu(first) > floor)) ++first;
    const int rank = k - first;
    if (rank < wanted) return false;
    // B = V_kept mu^{-1/2}: B^T G B = I.
    Eigen::MatrixXd B = gram.eigenvectors().rightCols(rank);
    for (int c = 0; c < rank; ++c) B.col(c) /= std::sqrt(mu(first + c));
    const Eigen::MatrixXd reduced = B.transpose() * H * B;
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> ritz(0.5 *
                                                              (reduced + reduced.transpose()));
    if (ritz.info() != Eigen::Success) return false;
    const Eigen::MatrixXd local = scale.asDiagonal() * B * ritz.eigenvectors().leftCols(wanted);
    out->coefficients = Eigen::MatrixXd::Zero(z.gram.rows(), wanted);
    for (int i = 0; i < k; ++i) out->coefficients.row(keep[i]) = local.row(i);
    out->ritz_values = ritz.eigenvalues().head(wanted);
    out->dropped_directions = first;
    out->ok = true;
    return true;
}

}  // namespace

RayleighRitzResult SolveRayleighRitz(const LobpcgGram& z, int wanted, double drop_tolerance) {
    RayleighRitzResult out;
    std::vector<int> all(static_cast<size_t>(z.x) + static_cast<size_t>(z.w) +
                         static_cast<size_t>(z.p));
    for (size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
    if (z.p > 0) {
        // A full-rank [X W P] first; any dependent direction restarts without P.
        if (SolveOn(z, all, wanted, drop_tolerance, &out) && out.dropped_directions == 0) {
            return out;
        }
        out = RayleighRitzResult{};
        out.dropped_p = true;
        all.resize(static_cast<size_t>(z.x) + static_cast<size_t>(z.w));
    }
    SolveOn(z, all, wanted, drop_tolerance, &out);
    out.dropped_p = z.p > 0;
    return out;
}

void PackUpper(const Eigen::MatrixXd& M, std::vector<double>* out) {
    for (Eigen::Index i = 0; i < M.rows(); ++i) {
        for (Eigen::Index j = i; j < M.cols(); ++j) out->push_back(M(i, j));
    }
}

Eigen::MatrixXd UnpackUpper(const std::vector<double>& in, Eigen::Index s, size_t* from) {
    Eigen::MatrixXd M(s, s);
    for (Eigen::Index i = 0; i < s; ++i) {
        for (Eigen::Index j = i; j < s; ++j) M(i, j) = M(j, i) = in[(*from)++];
    }
    return M;
}

}  // namespace certislam::certify
