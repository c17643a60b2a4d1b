// Quality of an alignment: fitness, point-to-plane Hessian, degeneracy test and information
// (no PCL in the front end).
#include "slam/frontend/registration_quality.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "slam/core/check.h"
#include "slam/core/se3.h"
#include "slam/frontend/point_kdtree.h"

namespace certislam::slam {
namespace {

// Applies the covariance floor: Omega <- (Omega^+ + diag(floor^2))^-1, through the eigen
// decomposition so unconstrained directions (zero eigenvalues) stay finite.
Matrix6 FloorCovariance(const Matrix6& information, const RegistrationConfig& config) {
    const Eigen::SelfAdjointEigenSolver<Matrix6> eig(0.5 * (information + information.transpose()));
    Vector6 inv_eigen;
    const double max_eigen = std::max(eig.eigenvalues().maxCoeff(), 1e-300);
    for (int i = 0; i < 6; ++i) {
        const double l = eig.eigenvalues()[i];
        inv_eigen[i] = l > 1e-12 * max_eigen ? 1.0 / l : 1e12 / max_eigen;
    }
    Matrix6 covariance =
        eig.eigenvectors() * inv_eigen.asDiagonal() * eig.eigenvectors().transpose();
    const double st = config.min_translation_sigma_m, sr = config.min_rotation_sigma_rad;
    covariance.diagonal() +=
        (Vector6() << st * st, st * st, st * st, sr * sr, sr * sr, sr * sr).finished();
    return covariance.inverse();
}

}  // namespace

Eigen::Vector3d PlaneNormal(const PointCloud& cloud, const std::vector<std::size_t>& indices) {
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const std::size_t j : indices) mean += cloud[j].cast<double>();
    mean /= static_cast<double>(indices.size());
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (const std::size_t j : indices) {
        const Eigen::Vector3d d = cloud[j].cast<double>() - mean;
        cov += d * d.transpose();
    }
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
    eig.computeDirect(cov);  // closed form, no iterations
    return eig.eigenvectors().col(0);
}

std::vector<Eigen::Vector3d> LocalPlaneNormals(const PointCloud& cloud, const PointKdTree& tree,
                                               int k) {
    std::vector<Eigen::Vector3d> normals;
    normals.reserve(cloud.size());
    std::vector<std::size_t> indices;
    std::vector<float> squared;
    for (const Eigen::Vector3f& p : cloud) {
        tree.Knn(p, static_cast<std::size_t>(k), indices, squared);
        normals.push_back(PlaneNormal(cloud, indices));
    }
    return normals;
}

RegistrationResult::Status EvaluateAlignment(const PointCloud& source, const PointCloud& target,
                                             const RegistrationConfig& config,
                                             RegistrationResult& result) {
    CERTISLAM_CHECK(!target.empty());
    const PointKdTree tree(target);
    return EvaluateAlignment(source, target, tree,
                             LocalPlaneNormals(target, tree, config.covariance_neighbours), config,
                             result);
}

RegistrationResult::Status EvaluateAlignment(const PointCloud& source, const PointCloud& target,
                                             const PointKdTree& tree,
                                             const std::vector<Eigen::Vector3d>& normals,
                                             const RegistrationConfig& config,
                                             RegistrationResult& result) {
    using Status = RegistrationResult::Status;
    CERTISLAM_CHECK(!target.empty() && normals.size() == target.size());
    const Eigen::Isometry3f T = result.T_target_source.cast<float>();
    const float gate = static_cast<float>(config.inlier_distance_m * config.inlier_distance_m);
    Matrix6 hessian = Matrix6::Zero();  // left perturbation, twist (v, w), target frame
    double squared_sum = 0.0;
    int inliers = 0;
    for (const Eigen::Vector3f& s : source) {
        const Eigen::Vector3f p = T * s;
        std::size_t j = 0;
        float d2 = 0.0f;
        if (!tree.Nearest(p, j, d2) || d2 > gate) continue;
        const Eigen::Vector3d& n = normals[j];
        const Eigen::Vector3d pd = p.cast<double>();
        const double r = n.dot(pd - target[j].cast<double>());  // point-to-plane residual
        Vector6 J;
        J << n, pd.cross(n);  // d r / d(v, w) for p' = p + w x p + v
        hessian += J * J.transpose();
        squared_sum += r * r;
        ++inliers;
    }
    result.fitness = source.empty() ? 0.0 : static_cast<double>(inliers) / source.size();
    result.inlier_rmse_m = inliers > 0 ? std::sqrt(squared_sum / inliers) : 0.0;
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> trans(hessian.topLeftCorner<3, 3>());
    result.translation_eigenvalues = trans.eigenvalues() / std::max(inliers, 1);
    const double max_eigen = trans.eigenvalues()[2];
    result.translation_eigen_ratio = max_eigen > 0 ? trans.eigenvalues()[0] / max_eigen : 0.0;
    // Residual variance, with a 1 cm floor so a perfect synthetic fit stays finite.
    const double variance = std::max(inliers > 6 ? squared_sum / (inliers - 6) : 1.0, 1e-4);
    const Matrix6 ad = Adjoint(result.T_target_source);
    result.information = FloorCovariance(ad.transpose() * (hessian / variance) * ad, config);
    // SE-Sync weights from the diagonal blocks (MATH.md: off-diagonal blocks ignored).
    result.tau = 3.0 / result.information.topLeftCorner<3, 3>().inverse().trace();
    result.kappa = 3.0 / (2.0 * result.information.bottomRightCorner<3, 3>().inverse().trace());
    if (inliers < 6 || result.fitness < config.min_fitness) return Status::kLowFitness;
    if (result.translation_eigen_ratio < config.min_translation_eigen_ratio) {
        return Status::kDegenerate;
    }
    return Status::kAccepted;
}

}  // namespace certislam::slam
