// The certificate in distributed form: each robot holds its own rows of S = Q - Lambda(X), so the
// smallest eigenvalue (distributed_lanczos.h) needs only S*v products (each robot reads its
// neighbours' entries of v at their public poses) and scalar sums over robots.
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <map>
#include <set>
#include <vector>

#include "slam/core/loop_closure.h"
#include "slam/core/partition.h"
#include "slam/core/pose_graph.h"

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

/// A robot's view of the joint graph for its rows of S.
struct LocalCertificateProblem {
    int robot = 0;                           ///< this robot
    CertificateRows rows;                    ///< own poses first, then neighbours' (local order)
    std::vector<slam::PoseId> public_ids;    ///< ids of rows.public_poses
    std::vector<slam::PoseId> neighbor_ids;  ///< ids of rows.neighbor_poses
    std::set<int> neighbor_robots;           ///< robots whose entries of v it reads
    double cost = 0.0;                       ///< own columns' share of tr(X Q X^T)
    double gradient_sq = 0.0;                ///< own columns' share of ||2 X S||_F^2
    double q_row_sum = 0.0;                  ///< largest absolute row sum of Q's own rows
    double x_norm_sq = 0.0;                  ///< ||X_own||_F^2
    double objective_noise = 0.0;            ///< own columns' share of f's rounding floor
};

/// Builds robot `robot`'s problem from its poses' block (`own_ids` in index order, X_own r x 4n),
/// every edge with an end at its poses, and the neighbours' blocks at the other ends (r x 4).
/// Returns false when an edge's far end has no block.
bool MakeLocalProblem(int robot, const std::vector<slam::PoseId>& own_ids,
                      const Eigen::MatrixXd& X_own, const std::vector<slam::LoopClosure>& edges,
                      const std::map<slam::PoseId, Eigen::MatrixXd>& neighbor_blocks,
                      LocalCertificateProblem* out);

}  // namespace certislam::certify
