// Levenberg-Marquardt with Ceres: one auto-differentiated residual block per edge.
#include "slam/backend/lm_baseline.h"

#include <ceres/ceres.h>

#include <Eigen/Geometry>
#include <cmath>
#include <stdexcept>
#include <vector>

#include "slam/backend/connection_laplacian.h"
#include "slam/backend/lm_se3_edge_cost.h"

namespace certislam::slam {
namespace {

/// Residual of one 2D edge with rotations as angles.
struct Se2EdgeResidual {
    Eigen::Matrix2d R;
    Eigen::Vector2d t;
    double sqrt_kappa, sqrt_tau;
    template <typename T>
    static Eigen::Matrix<T, 2, 2> Rot(const T& a) {
        Eigen::Matrix<T, 2, 2> M;
        M << cos(a), -sin(a), sin(a), cos(a);
        return M;
    }
    template <typename T>
    bool operator()(const T* ai, const T* ti, const T* aj, const T* tj, T* out) const {
        const Eigen::Matrix<T, 2, 2> Ri = Rot(ai[0]);
        const Eigen::Matrix<T, 2, 2> E = Rot(aj[0]) - Ri * R.cast<T>();
        const Eigen::Matrix<T, 2, 1> e = Eigen::Map<const Eigen::Matrix<T, 2, 1>>(tj) -
                                         Eigen::Map<const Eigen::Matrix<T, 2, 1>>(ti) -
                                         Ri * t.cast<T>();
        for (int k = 0; k < 4; ++k) out[k] = T(sqrt_kappa) * E(k % 2, k / 2);
        for (int k = 0; k < 2; ++k) out[4 + k] = T(sqrt_tau) * e[k];
        return true;
    }
};

void Require(bool ok, const std::string& field, double value, const std::string& rule) {
    if (!ok) {
        throw std::invalid_argument("LmConfig." + field + " = " + std::to_string(value) +
                                    ": must be " + rule);
    }
}

/// Parameters: rot[g] (quaternion x y z w, or one angle) and trans[g] per pose.
struct Parameters {
    std::vector<std::vector<double>> rot, trans;
};

Parameters FromPoses(const PoseMatrix& P, int d, int n) {
    Parameters p{std::vector<std::vector<double>>(n), std::vector<std::vector<double>>(n)};
    for (int g = 0; g < n; ++g) {
        const Eigen::MatrixXd R = P.block(0, BlockColumn(g, d), d, d);
        const Eigen::VectorXd t = P.col(BlockColumn(g, d) + d);
        p.trans[g].assign(t.data(), t.data() + d);
        if (d == 3) {
            const Eigen::Quaterniond q{Eigen::Matrix3d(R)};
            p.rot[g] = {q.x(), q.y(), q.z(), q.w()};
        } else {
            p.rot[g] = {std::atan2(R(1, 0), R(0, 0))};
        }
    }
    return p;
}

PoseMatrix ToPoses(const Parameters& p, int d, int n) {
    PoseMatrix P(d, (d + 1) * n);
    for (int g = 0; g < n; ++g) {
        const auto& r = p.rot[g];
        if (d == 3) {
            P.block(0, BlockColumn(g, d), 3, 3) =
                Eigen::Quaterniond(r[3], r[0], r[1], r[2]).normalized().toRotationMatrix();
        } else {
            P.block(0, BlockColumn(g, d), 2, 2) = Se2EdgeResidual::Rot(r[0]);
        }
        P.col(BlockColumn(g, d) + d) = Eigen::Map<const Eigen::VectorXd>(p.trans[g].data(), d);
    }
    return P;
}

void AddEdges(const PoseGraph& graph, Parameters* p, ceres::Problem* problem) {
    for (const auto& e : graph.edges) {
        const double sk = std::sqrt(e.weight * e.kappa), st = std::sqrt(e.weight * e.tau);
        if (sk == 0.0 && st == 0.0) continue;
        ceres::CostFunction* cost = nullptr;
        if (graph.d == 3) {
            cost = new Se3EdgeCost(e.R, e.t, sk, st);
        } else {
            cost = new ceres::AutoDiffCostFunction<Se2EdgeResidual, 6, 1, 2, 1, 2>(
                new Se2EdgeResidual{e.R, e.t, sk, st});
        }
        problem->AddResidualBlock(cost, nullptr, p->rot[e.i].data(), p->trans[e.i].data(),
                                  p->rot[e.j].data(), p->trans[e.j].data());
    }
}

}  // namespace

void LmConfig::Validate() const {
    Require(max_iterations > 0, "max_iterations", max_iterations, "> 0");
    Require(function_tolerance > 0.0, "function_tolerance", function_tolerance, "> 0");
    Require(gradient_tolerance > 0.0, "gradient_tolerance", gradient_tolerance, "> 0");
    Require(parameter_tolerance > 0.0, "parameter_tolerance", parameter_tolerance, "> 0");
    Require(num_threads >= 1, "num_threads", num_threads, ">= 1");
}

LmResult SolveLm(const PoseGraph& graph, const PoseMatrix& initial, const LmConfig& config) {
    config.Validate();
    const int d = graph.d, n = graph.n;
    Parameters p = FromPoses(initial, d, n);
    ceres::Problem problem;
    AddEdges(graph, &p, &problem);
    for (int g = 0; g < n; ++g) {
        if (!problem.HasParameterBlock(p.rot[g].data())) continue;  // pose without edges
        if (d == 3) problem.SetManifold(p.rot[g].data(), new ceres::EigenQuaternionManifold);
    }
    if (n > 0 && problem.HasParameterBlock(p.rot[0].data())) {
        problem.SetParameterBlockConstant(p.rot[0].data());
        problem.SetParameterBlockConstant(p.trans[0].data());
    }
    ceres::Solver::Options options;
    options.minimizer_type = ceres::TRUST_REGION;
    options.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
    options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
    options.max_num_iterations = config.max_iterations;
    options.function_tolerance = config.function_tolerance;
    options.gradient_tolerance = config.gradient_tolerance;
    options.parameter_tolerance = config.parameter_tolerance;
    options.num_threads = config.num_threads;
    ceres::Solver::Summary summary;
    ceres::Solve(options, &problem, &summary);
    LmResult result;
    result.poses = ToPoses(p, d, n);
    result.initial_cost = Objective(graph, initial);
    result.cost = Objective(graph, result.poses);
    result.iterations = summary.num_successful_steps + summary.num_unsuccessful_steps;
    result.seconds = summary.total_time_in_seconds;
    result.message = summary.message;
    if (summary.termination_type == ceres::CONVERGENCE) {
        result.status = LmResult::Status::kConverged;
    } else if (summary.termination_type == ceres::NO_CONVERGENCE) {
        result.status = LmResult::Status::kNoConvergence;
    }
    return result;
}

namespace {

/// R(q) of a unit quaternion (x, y, z, w) as Eigen's toRotationMatrix forms it, and its four
/// partial derivatives dR/dx, dR/dy, dR/dz, dR/dw.
void RotationAndDerivatives(const double* q, Eigen::Matrix3d* R, Eigen::Matrix3d* dR) {
    const double x = q[0], y = q[1], z = q[2], w = q[3];
    *R << 1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w),  //
        2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w),    //
        2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y);
    if (dR == nullptr) return;
    dR[0] << 0, 2 * y, 2 * z, 2 * y, -4 * x, -2 * w, 2 * z, 2 * w, -4 * x;
    dR[1] << -4 * y, 2 * x, 2 * w, 2 * x, 0, 2 * z, -2 * w, 2 * z, -4 * y;
    dR[2] << -4 * z, -2 * w, 2 * x, 2 * w, -4 * z, 2 * y, 2 * x, 2 * y, 0;
    dR[3] << 0, -2 * z, 2 * y, 2 * z, 0, -2 * x, -2 * y, 2 * x, 0;
}

}  // namespace

bool Se3EdgeCost::Evaluate(double const* const* parameters, double* residuals,
                           double** jacobians) const {
    const bool want = jacobians != nullptr;
    Eigen::Matrix3d Ri, Rj, dRi[4], dRj[4];
    RotationAndDerivatives(parameters[0], &Ri, want && jacobians[0] ? dRi : nullptr);
    RotationAndDerivatives(parameters[2], &Rj, want && jacobians[2] ? dRj : nullptr);
    const Eigen::Map<const Eigen::Vector3d> ti(parameters[1]), tj(parameters[3]);
    const Eigen::Matrix3d E = Rj - Ri * R_;
    const Eigen::Vector3d e = tj - ti - Ri * t_;
    for (int k = 0; k < 9; ++k) residuals[k] = sqrt_kappa_ * E(k % 3, k / 3);
    for (int k = 0; k < 3; ++k) residuals[9 + k] = sqrt_tau_ * e[k];
    if (!want) return true;
    // Row-major 12 x size blocks; the residual's rows 0-8 are vec(E) (column-major), 9-11 e.
    using Rows = Eigen::Matrix<double, 12, Eigen::Dynamic, Eigen::RowMajor>;
    if (jacobians[0]) {
        Eigen::Map<Eigen::Matrix<double, 12, 4, Eigen::RowMajor>> J(jacobians[0]);
        for (int c = 0; c < 4; ++c) {
            const Eigen::Matrix3d dE = -dRi[c] * R_;
            for (int k = 0; k < 9; ++k) J(k, c) = sqrt_kappa_ * dE(k % 3, k / 3);
            J.block<3, 1>(9, c) = -sqrt_tau_ * (dRi[c] * t_);
        }
    }
    if (jacobians[1]) {
        Eigen::Map<Rows> J(jacobians[1], 12, 3);
        J.setZero();
        J.bottomRows<3>() = -sqrt_tau_ * Eigen::Matrix3d::Identity();
    }
    if (jacobians[2]) {
        Eigen::Map<Eigen::Matrix<double, 12, 4, Eigen::RowMajor>> J(jacobians[2]);
        J.bottomRows<3>().setZero();
        for (int c = 0; c < 4; ++c) {
            for (int k = 0; k < 9; ++k) J(k, c) = sqrt_kappa_ * dRj[c](k % 3, k / 3);
        }
    }
    if (jacobians[3]) {
        Eigen::Map<Rows> J(jacobians[3], 12, 3);
        J.setZero();
        J.bottomRows<3>() = sqrt_tau_ * Eigen::Matrix3d::Identity();
    }
    return true;
}

}  // namespace certislam::slam
