// The manifold of the lifted variable: a product, per pose, of St(d, r) x R^r (MATH.md).
#pragma once

#include <Eigen/Core>

namespace certislam::slam {

/// Orthogonal projection of V (r x (d+1)k, same layout as X) onto the tangent space at X:
/// each rotation block V_y -> V_y - Y sym(Y^T V_y); translation columns unchanged.
Eigen::MatrixXd ProjectToTangent(const Eigen::MatrixXd& X, const Eigen::MatrixXd& V, int d);

/// Polar retraction: each rotation block of X + V replaced by its polar factor (closest point on
/// St(d, r)); translations X + V.
Eigen::MatrixXd Retract(const Eigen::MatrixXd& X, const Eigen::MatrixXd& V, int d);

/// Projects every rotation block of X onto St(d, r) (polar factor); translations unchanged.
Eigen::MatrixXd ProjectToManifold(const Eigen::MatrixXd& X, int d);

/// Weingarten term of the Riemannian Hessian: each rotation block of the result is
/// V_y sym(Y^T G_y) (G = Euclidean gradient); translation columns are zero.
Eigen::MatrixXd WeingartenTerm(const Eigen::MatrixXd& X, const Eigen::MatrixXd& G,
                               const Eigen::MatrixXd& V, int d);

}  // namespace certislam::slam
