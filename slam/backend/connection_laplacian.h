// The connection Laplacian Q of a pose graph: f(X) = tr(X Q X^T) for X = [Y_1 p_1 ... Y_n p_n].
#pragma once

#include <Eigen/SparseCore>

#include "slam/core/pose_graph.h"

namespace certislam::slam {

/// Builds the (d+1)n x (d+1)n connection Laplacian (MATH.md, "The lifted problem"). Edge (i,j)
/// with Omega = diag(kappa I_d, tau) and T~ = [R~ t~; 0 1] contributes
///   Q_jj += Omega,  Q_ii += T~ Omega T~^T,  Q_ij -= T~ Omega,  Q_ji -= Omega T~^T,
/// scaled by the edge's robust weight, except that the rotation block of Q_ii is kappa I (not
/// kappa R~ R~^T) as in SE-Sync's L(G~rho). Then tr(X Q X^T) equals the SE-Sync objective (no
/// 1/2) even where the file's R~ is not exactly orthogonal (unnormalised quaternions).
Eigen::SparseMatrix<double> ConnectionLaplacian(const PoseGraph& graph);

/// The SE-Sync objective f(R, t) of poses P (d x (d+1)n, blocks [R_g t_g]), weights included,
/// with ||R_i R~||^2 counted as ||R_i||^2 (SE-Sync's Q; equal when R~ is orthogonal).
double Objective(const PoseGraph& graph, const PoseMatrix& poses);

}  // namespace certislam::slam
