// V A for a short, wide dense V (the lifted layout, r x n) and a column-major sparse A: the
// product the trust-region solvers make several times per CG iteration.
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>

namespace certislam::slam {

/// V A with V r x m (column-major, as Eigen::MatrixXd) and A m x n. Same result as Eigen's
/// V * A to rounding, and faster (`certislam bench backend` compares them): each output column
/// is one pass over A's column with r accumulators held in registers, where Eigen's dense x
/// sparse product walks A once per row of V.
Eigen::MatrixXd DenseTimesSparse(const Eigen::MatrixXd& V, const Eigen::SparseMatrix<double>& A);

}  // namespace certislam::slam
