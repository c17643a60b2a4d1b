// Initial guesses that need no accurate prior: chordal relaxation and odometry composition.
#pragma once

#include <Eigen/Core>
#include <cstdint>

#include "slam/core/pose_graph.h"

namespace certislam::slam {

/// Chordal initialisation (centralised): rotations by the sparse linear least squares
/// min sum kappa ||R_j - R_i R~_ij||_F^2 with R_0 = I, each projected to SO(d); translations by
/// RecoverTranslations. Returns d x (d+1)n poses. (A distributed variant is future work.)
PoseMatrix ChordalInitialization(const PoseGraph& graph);

/// Odometry initialisation: poses composed along a BFS spanning tree from pose 0 that prefers
/// |i - j| = 1 edges (so it is the odometry chain when the file has one), pose 0 = identity.
PoseMatrix OdometryInitialization(const PoseGraph& graph);

/// Optimal translations for fixed rotations (blocks R_g of `poses`; translations ignored):
/// min sum tau ||t_j - t_i - R_i t~_ij||^2 with t_0 = 0 by a sparse Cholesky. Returns the poses
/// with the translations replaced.
PoseMatrix RecoverTranslations(const PoseGraph& graph, const PoseMatrix& poses);

/// Lifts d x (d+1)n poses to rank r >= d: X = U P with U an r x d matrix with orthonormal
/// columns drawn from a fixed seed (U = I when r == d).
Eigen::MatrixXd LiftToRank(const PoseMatrix& poses, int r, std::uint64_t seed = 1);

}  // namespace certislam::slam
