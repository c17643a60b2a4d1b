// Rounding a lifted solution X (r x (d+1)n) back to poses in SE(d).
#pragma once

#include <Eigen/Core>

#include "slam/core/pose_graph.h"

namespace certislam::slam {

/// SE-Sync rounding: thin SVD of the rotation part of X, top-d factor Sigma_d V_d^T; reflected
/// when fewer than half of the d x d blocks have positive determinant; each block projected to
/// SO(d) (determinant sign fixed); translations re-solved optimally for those rotations
/// (RecoverTranslations, t_0 = 0). Returns d x (d+1)n poses.
PoseMatrix RoundSolution(const PoseGraph& graph, const Eigen::MatrixXd& X);

/// dpgo's anchor-based rounding for the distributed case: T = Y_a^T X with Y_a the anchor's
/// rotation block; each rotation block projected to SO(d); translations Y_a^T (p_i - p_a).
PoseMatrix RoundWithAnchor(const Eigen::MatrixXd& X, int d, int anchor = 0);

/// Closest rotation in SO(d) to a d x d matrix M (SVD, determinant sign fixed).
Eigen::MatrixXd ProjectToRotation(const Eigen::MatrixXd& M);

}  // namespace certislam::slam
