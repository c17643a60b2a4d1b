// The smallest eigenpair of S = Q - Lambda(X) held as rows by robots, by block LOBPCG (Knyazev
// 2001) preconditioned by block Jacobi: each robot applies (S_kk + tau_k I)^{-1} to its own
// segment of the residual, with no message. One iteration is one neighbour exchange (the public
// entries of the preconditioned residuals W), one sum over robots of the small Gram matrices of
// [X W P] against I and S, and a Rayleigh-Ritz problem every robot solves alike from those sums.
// Plain data: the robots' messages are counted, not sent.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "certify/distributed/distributed_certificate.h"

namespace certislam::certify {

/// Columns of a LOBPCG block at most (a vector message carries one block).
inline constexpr int kMaxBlockSize = 16;

/// Settings of DistributedLobpcg.
struct LobpcgSettings {
    int block_size = 6;  ///< Ritz vectors iterated together, 1..16 (the certificate reads one)
    int max_iterations = 2000;  ///< iterations at most, >= 1
    /// Converged when ||S x - theta x|| <= tolerance * ||S||_inf for the smallest Ritz pair
    /// (||S||_inf, the largest absolute row sum, bounds lambda_max(S) from above).
    double tolerance = 1e-10;
    /// Each robot's preconditioner is (S_kk + tau I)^{-1} with tau = shift_relative * ||S||_inf,
    /// multiplied by shift_growth until S_kk + tau I factorises (S_kk is indefinite at saddles).
    double shift_relative = 1e-10;
    double shift_growth = 10.0;  ///< > 1
    /// Directions of [X W P] whose scaled Gram eigenvalue is below this times the largest are
    /// linearly dependent: P is dropped (restart), then such directions of [X W] are truncated.
    double drop_tolerance = 1e-12;
    std::uint64_t seed = 20261121;  ///< start block seed (robot id added)

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// Result of DistributedLobpcg, with the messages counted as if every robot were remote.
struct LobpcgResult {
    enum class Status {
        kConverged,     ///< the smallest Ritz pair's exact residual is below tolerance
        kNotConverged,  ///< max_iterations reached first, or the block lost independence
    };
    Status status = Status::kNotConverged;
    double lambda_min = 0.0;              ///< Rayleigh quotient of `vector`
    double residual = 0.0;                ///< ||S v - lambda v|| (global, exact product)
    double scale = 0.0;                   ///< ||S||_inf (the tolerance's reference)
    std::vector<Eigen::VectorXd> vector;  ///< the unit Ritz vector, one segment per robot
    int iterations = 0;                   ///< LOBPCG iterations
    int products = 0;                     ///< S v products (columns multiplied, all exchanges)
    int vector_exchanges = 0;             ///< rounds of neighbour exchange of public entries
    int scalar_reductions = 0;            ///< sums (or maxima) over robots of small arrays
    double scalars_reduced = 0.0;         ///< doubles every robot contributes to those sums
    double entries_exchanged = 0.0;       ///< doubles of public entries sent, all exchanges
    int restarts = 0;                     ///< iterations whose P was dropped
    double max_shift = 0.0;               ///< largest tau any robot's preconditioner needed
};

/// Smallest eigenpair of S held as rows by robots (the interface of DistributedMinEigenpair): one
/// LobpcgParticipant per robot, their messages delivered in memory (RunInMemory).
LobpcgResult DistributedLobpcg(const std::vector<CertificateRows>& robots,
                               const LobpcgSettings& settings = {});

}  // namespace certislam::certify
