// The certificate in distributed form: each robot holds its own rows of S = Q - Lambda(X), and
// the smallest eigenvalue is found by Lanczos whose only coupling is S*v products (each robot
// needs its neighbours' entries of v at their public poses) and scalar sums over robots.
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <cstdint>
#include <vector>

#include "slam/core/partition.h"

namespace certislam::certify {

/// One robot's share of S: its rows, split into the own block and the neighbour columns.
struct CertificateRows {
    int robot = 0;                    ///< robot id
    int d = 3;                        ///< dimension
    int first_pose = 0;               ///< global index of the robot's first pose
    int poses = 0;                    ///< number of own poses
    Eigen::SparseMatrix<double> own;  ///< S rows x own columns, (d+1)k x (d+1)k
    Eigen::SparseMatrix<double> nbr;  ///< S rows x neighbour entries, (d+1)k x (d+1)|nbr|
    std::vector<int> neighbor_poses;  ///< global poses of other robots it reads (ascending)
    std::vector<int> public_poses;    ///< own global poses that other robots read (ascending)
    double trace_lambda = 0.0;        ///< sum of tr(Lambda_i) over own poses
};

/// Builds robot `robot`'s rows of S from Q (only the robot's columns are read: its edges) and X
/// (only the robot's own and neighbour pose columns are read: what it holds plus what its
/// neighbours publish during RBCD). Lambda_i = sym((X Q)_i^T Y_i) for the robot's poses i.
CertificateRows MakeCertificateRows(const Eigen::SparseMatrix<double>& Q, const Eigen::MatrixXd& X,
                                    int d, const slam::Partition& partition, int robot);

/// Entries of v_k (the robot's segment, (d+1)k) at its public poses, in public_poses order:
/// the message a robot sends its neighbours for one product.
Eigen::VectorXd PublicEntries(const CertificateRows& rows, const Eigen::VectorXd& v_own);

/// (S v)_k from the own segment and the neighbours' entries (in neighbor_poses order).
Eigen::VectorXd MultiplyRows(const CertificateRows& rows, const Eigen::VectorXd& v_own,
                             const Eigen::VectorXd& v_neighbors);

/// Settings of DistributedMinEigenpair.
struct DistributedEigenConfig {
    int max_krylov = 400;           ///< Lanczos steps (full reorthogonalisation), >= 2
    double tolerance = 1e-10;       ///< stop when the Ritz residual <= this * ||S|| estimate
    int check_every = 10;           ///< Ritz values computed every this many steps, >= 1
    std::uint64_t seed = 20261121;  ///< start vector seed

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// Result of DistributedMinEigenpair.
struct DistributedEigenResult {
    enum class Status {
        kConverged,     ///< Ritz residual below tolerance
        kNotConverged,  ///< max_krylov steps reached first (lambda is the best Ritz value)
    };
    Status status = Status::kNotConverged;
    double lambda_min = 0.0;              ///< smallest Ritz value (Rayleigh quotient)
    double residual = 0.0;                ///< ||S v - lambda v|| (global)
    std::vector<Eigen::VectorXd> vector;  ///< the Ritz vector, one segment per robot
    int products = 0;                     ///< S v products (one neighbour exchange each)
    int scalar_reductions = 0;            ///< sums over robots of one or more scalars
    double entries_exchanged = 0.0;       ///< doubles sent between robots, all products
};

/// Smallest eigenpair of S held as rows by robots: Lanczos with full reorthogonalisation, each
/// product S v formed robot by robot from PublicEntries messages, inner products summed over
/// robots. Plain data in and out (the system moves the messages onto the network).
DistributedEigenResult DistributedMinEigenpair(const std::vector<CertificateRows>& robots,
                                               const DistributedEigenConfig& config = {});

}  // namespace certislam::certify
