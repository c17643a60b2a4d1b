// The local-search baseline's 3D edge residual with its analytic Jacobians (Ceres), so Ceres
// need not differentiate it by dual numbers at every Levenberg-Marquardt iteration.
#pragma once

#include <ceres/sized_cost_function.h>

#include <Eigen/Core>

namespace certislam::slam {

/// Residual of one 3D edge with rotations as unit quaternions (x, y, z, w; Eigen's order):
/// sqrt(w kappa) vec(R_j - R_i R~) and sqrt(w tau) (t_j - t_i - R_i t~), the two terms of the
/// SE-Sync objective, with its Jacobians in the quaternions' ambient coordinates.
class Se3EdgeCost final : public ceres::SizedCostFunction<12, 4, 3, 4, 3> {
  public:
    Se3EdgeCost(const Eigen::Matrix3d& R, const Eigen::Vector3d& t, double sqrt_kappa,
                double sqrt_tau)
        : R_(R), t_(t), sqrt_kappa_(sqrt_kappa), sqrt_tau_(sqrt_tau) {}

    /// Parameters: q_i, t_i, q_j, t_j.
    bool Evaluate(double const* const* parameters, double* residuals,
                  double** jacobians) const override;

  private:
    Eigen::Matrix3d R_;
    Eigen::Vector3d t_;
    double sqrt_kappa_, sqrt_tau_;
};

}  // namespace certislam::slam
