// Levenberg-Marquardt with Ceres: one auto-differentiated residual block per edge.
#include "slam/backend/lm_baseline.h"

#include <ceres/ceres.h>

#include <Eigen/Geometry>
#include <cmath>
#include <stdexcept>
#include <vector>

#include "slam/backend/connection_laplacian.h"

namespace certislam::slam {
namespace {

/// Residual of one 3D edge: sqrt(w kappa) vec(R_j - R_i R~) and sqrt(w tau)(t_j - t_i - R_i t~).
struct Se3EdgeResidual {
    Eigen::Matrix3d R;
    Eigen::Vector3d t;
    double sqrt_kappa, sqrt_tau;
    template <typename T>
    bool operator()(const T* qi, const T* ti, const T* qj, const T* tj, T* out) const {
        const Eigen::Matrix<T, 3, 3> Ri =
            Eigen::Map<const Eigen::Quaternion<T>>(qi).toRotationMatrix();
        const Eigen::Matrix<T, 3, 3> Rj =
            Eigen::Map<const Eigen::Quaternion<T>>(qj).toRotationMatrix();
        const Eigen::Matrix<T, 3, 3> E = Rj - Ri * R.cast<T>();
        const Eigen::Matrix<T, 3, 1> e = Eigen::Map<const Eigen::Matrix<T, 3, 1>>(tj) -
                                         Eigen::Map<const Eigen::Matrix<T, 3, 1>>(ti) -
                                         Ri * t.cast<T>();
        for (int k = 0; k < 9; ++k) out[k] = T(sqrt_kappa) * E(k % 3, k / 3);
        for (int k = 0; k < 3; ++k) out[9 + k] = T(sqrt_tau) * e[k];
        return true;
    }
};

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
            cost = new ceres::AutoDiffCostFunction<Se3EdgeResidual, 12, 4, 3, 4, 3>(
                new Se3EdgeResidual{e.R, e.t, sk, st});
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

}  // namespace certislam::slam
