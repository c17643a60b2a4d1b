// Escaping a saddle of the rank-r relaxation along a negative-curvature direction of S, at rank
// r + 1 (Riemannian staircase; SE-Sync, Rosen et al. IJRR 2019, Sec. 4.3; MATH.md).
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>

namespace certislam::certify {

/// Settings of the escape line search.
struct EscapeConfig {
    /// First step, in multiples of sqrt(n) (v is a unit vector over all n poses, so a step of
    /// sqrt(n) moves each pose by about one unit): "starts large". > 0.
    double initial_step_per_sqrt_pose = 10.0;
    int max_halvings = 60;  ///< the step is halved at most this many times, > 0

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// Outcome of EscapeSaddle.
struct EscapeResult {
    enum class Status {
        kEscaped,  ///< X has rank r + 1, lower cost, gradient above the tolerance
        kFailed,   ///< no step in the halving sequence decreased the cost
    };
    Status status = Status::kFailed;
    Eigen::MatrixXd X;           ///< (r+1) x (d+1)n point on the manifold (input lifted if failed)
    double step = 0.0;           ///< accepted step alpha
    double cost_before = 0.0;    ///< f(X) at the saddle
    double cost_after = 0.0;     ///< f at the accepted point
    double gradient_norm = 0.0;  ///< ||grad f|| at the accepted point
    int halvings = 0;            ///< halvings spent
};

/// From X (r x (d+1)n, blocks [Y_i p_i]) and v with v^T S v < 0: X_+ = [X; 0], tangent direction
/// V = e_{r+1} v^T (tangent since Y_i^T e_{r+1} = 0), polar retraction of X_+ + alpha V with
/// alpha halved from a large value until f decreases and ||grad f|| > gradient_tolerance (so
/// the next RBCD run does not stop at once).
EscapeResult EscapeSaddle(const Eigen::SparseMatrix<double>& Q, const Eigen::MatrixXd& X, int d,
                          const Eigen::VectorXd& v, double gradient_tolerance,
                          const EscapeConfig& config = {});

}  // namespace certislam::certify
