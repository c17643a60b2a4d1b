// Lift by one rank and line-search along the negative-curvature eigenvector.
#include "certify/saddle_escape.h"

#include <cmath>
#include <stdexcept>
#include <string>

#include "slam/backend/rbcd.h"
#include "slam/backend/stiefel.h"
#include "slam/core/check.h"

namespace certislam::certify {

void EscapeConfig::Validate() const {
    if (!(initial_step_per_sqrt_pose > 0.0)) {
        throw std::invalid_argument("EscapeConfig.initial_step_per_sqrt_pose = " +
                                    std::to_string(initial_step_per_sqrt_pose) + ": must be > 0");
    }
    if (max_halvings <= 0) {
        throw std::invalid_argument("EscapeConfig.max_halvings = " + std::to_string(max_halvings) +
                                    ": must be > 0");
    }
}

EscapeResult EscapeSaddle(const Eigen::SparseMatrix<double>& Q, const Eigen::MatrixXd& X, int d,
                          const Eigen::VectorXd& v, double gradient_tolerance,
                          const EscapeConfig& config) {
    config.Validate();
    CERTISLAM_CHECK(v.size() == X.cols() && X.cols() % (d + 1) == 0);
    const int r = static_cast<int>(X.rows());
    const int n = static_cast<int>(X.cols()) / (d + 1);
    EscapeResult result;
    Eigen::MatrixXd lifted = Eigen::MatrixXd::Zero(r + 1, X.cols());
    lifted.topRows(r) = X;
    Eigen::MatrixXd V = Eigen::MatrixXd::Zero(r + 1, X.cols());
    V.row(r) = v.transpose();
    result.cost_before = slam::LiftedCost(Q, lifted);
    result.X = lifted;
    double alpha = config.initial_step_per_sqrt_pose * std::sqrt(static_cast<double>(n));
    for (int k = 0; k <= config.max_halvings; ++k, alpha *= 0.5) {
        const Eigen::MatrixXd trial = slam::Retract(lifted, alpha * V, d);
        const double cost = slam::LiftedCost(Q, trial);
        if (!(cost < result.cost_before)) continue;
        const double grad = slam::RiemannianGradient(Q, trial, d).norm();
        if (grad <= gradient_tolerance) continue;
        result.status = EscapeResult::Status::kEscaped;
        result.X = trial;
        result.step = alpha;
        result.cost_after = cost;
        result.gradient_norm = grad;
        result.halvings = k;
        return result;
    }
    result.halvings = config.max_halvings;
    result.cost_after = result.cost_before;
    return result;
}

}  // namespace certislam::certify
