// Scan-to-scan registration: the settings check, the yaw guess, clouds prepared once (trees,
// normals, GICP covariances) and RegisterScans by GICP (Segal et al. 2009) solved by damped
// Gauss-Newton.
#include "slam/frontend/registration.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include <algorithm>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

#include "slam/core/check.h"
#include "slam/frontend/downsample.h"
#include "slam/frontend/gicp_cycle.h"
#include "slam/frontend/point_kdtree.h"
#include "slam/frontend/registration_quality.h"

namespace certislam::slam {
namespace {

[[noreturn]] void Invalid(const std::string& field, double value, const std::string& rule) {
    throw std::invalid_argument("RegistrationConfig." + field + " = " + std::to_string(value) +
                                ": must be " + rule);
}

// GICP's plane-to-plane covariance (Segal et al. 2009, Sec. III-B) of the points `indices`: raw
// moments of float products, the smallest-|eigenvalue| direction set to epsilon = 1e-3 and the
// others to 1 (PCL's computeCovariances arithmetic and gicp_epsilon_ default).
Eigen::Matrix3d PlaneCovariance(const PointCloud& cloud, const std::vector<std::size_t>& indices) {
    constexpr double kGicpEpsilon = 1e-3;
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (const std::size_t j : indices) {
        const Eigen::Vector3f& p = cloud[j];
        mean += p.cast<double>();
        for (int r = 0; r < 3; ++r) {
            for (int c = 0; c <= r; ++c) cov(r, c) += static_cast<double>(p[r] * p[c]);
        }
    }
    const auto k = static_cast<double>(indices.size());
    mean /= k;
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c <= r; ++c) cov(c, r) = cov(r, c) = cov(r, c) / k - mean[r] * mean[c];
    }
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
    eig.computeDirect(cov);  // closed form, no iterations
    int smallest = 0;  // singular values are |eigenvalues|: float rounding can make one negative
    eig.eigenvalues().cwiseAbs().minCoeff(&smallest);
    const Eigen::Vector3d u = eig.eigenvectors().col(smallest);
    return Eigen::Matrix3d::Identity() - (1.0 - kGicpEpsilon) * u * u.transpose();
}

struct StageResult {
    Eigen::Matrix4f T_target_source;
    bool converged = false;
};

}  // namespace

struct PreparedCloud::Stage {
    PointCloud points;                         ///< downsampled at the stage's voxel
    std::unique_ptr<PointKdTree> tree;         ///< over points (null below min_points)
    std::vector<Eigen::Vector3d> normals;      ///< PlaneNormal of each k-NN (fine stage only)
    std::vector<Eigen::Matrix3d> covariances;  ///< GICP's, per point (empty below min_points)
};

namespace {

// Downsampled points; their tree, covariances and (with `normals`) planes only when registration
// will use them.
std::unique_ptr<PreparedCloud::Stage> MakeStage(const PointCloud& cloud, double voxel_m,
                                                const RegistrationConfig& config, bool normals) {
    auto stage = std::make_unique<PreparedCloud::Stage>();
    stage->points = VoxelDownsample(cloud, voxel_m);
    if (static_cast<int>(stage->points.size()) < config.min_points) return stage;
    stage->tree = std::make_unique<PointKdTree>(stage->points);
    // One k-NN pass for GICP's covariances and the quality test's planes.
    stage->covariances.reserve(stage->points.size());
    if (normals) stage->normals.reserve(stage->points.size());
    std::vector<std::size_t> indices;
    std::vector<float> squared;
    for (const Eigen::Vector3f& p : stage->points) {
        stage->tree->Knn(p, static_cast<std::size_t>(config.covariance_neighbours), indices,
                         squared);
        stage->covariances.push_back(PlaneCovariance(stage->points, indices));
        if (normals) stage->normals.push_back(PlaneNormal(stage->points, indices));
    }
    return stage;
}

/// A source point matched to its nearest target point, and the weight of their difference.
struct GicpPair {
    std::size_t source, target;
    Eigen::Matrix3d weight;  ///< (C_target + R C_source R^T)^-1 at the iterate that matched them
};

/// sum_i d_i^T W_i d_i with d_i = target_i - (R source_i + t): Segal et al.'s Eq. (2) cost.
double GicpCost(const PreparedCloud::Stage& source, const PreparedCloud::Stage& target,
                const std::vector<GicpPair>& pairs, const Eigen::Matrix3d& R,
                const Eigen::Vector3d& t) {
    double cost = 0.0;
    for (const GicpPair& p : pairs) {
        const Eigen::Vector3d d = target.points[p.target].cast<double>() -
                                  (R * source.points[p.source].cast<double>() + t);
        cost += d.dot(p.weight * d);
    }
    return cost;
}

/// Segal et al.'s Eq. (2) linearised at (R, t): every source point matched to its nearest target
/// point within sqrt(gate) (into `pairs`), the Gauss-Newton Hessian H and gradient g of the left
/// perturbation; returns the cost.
double LinearizeGicp(const PreparedCloud::Stage& source, const PreparedCloud::Stage& target,
                     const Eigen::Matrix3d& R, const Eigen::Vector3d& t, float gate,
                     std::vector<GicpPair>* pairs, Eigen::Matrix<double, 6, 6>* H,
                     Eigen::Matrix<double, 6, 1>* g) {
    pairs->clear();
    H->setZero();
    g->setZero();
    double cost = 0.0;
    for (std::size_t i = 0; i < source.points.size(); ++i) {
        const Eigen::Vector3d q = R * source.points[i].cast<double>() + t;
        std::size_t j = 0;
        float squared = 0.0f;
        if (!target.tree->Nearest(q.cast<float>(), j, squared) || squared > gate) continue;
        const Eigen::Matrix3d W =
            (target.covariances[j] + R * source.covariances[i] * R.transpose()).inverse();
        pairs->push_back({i, j, W});
        const Eigen::Vector3d d = target.points[j].cast<double>() - q;
        // d(d)/d(xi) = [q]x for the rotation part, -I for the translation part.
        Eigen::Matrix<double, 3, 6> J;
        J << 0.0, -q.z(), q.y(), -1.0, 0.0, 0.0,  //
            q.z(), 0.0, -q.x(), 0.0, -1.0, 0.0,   //
            -q.y(), q.x(), 0.0, 0.0, 0.0, -1.0;
        const Eigen::Matrix<double, 6, 3> JtW = J.transpose() * W;
        H->noalias() += JtW * J;
        g->noalias() += JtW * d;
        cost += d.dot(W * d);
    }
    return cost;
}

// One GICP run from `guess` on prepared stages: each iteration matches every source point to its
// nearest target point within the gate, weighs the pair by (C_t + R C_s R^T)^-1 (Segal et al.
// 2009, Eq. (2)) and takes a Levenberg-Marquardt-damped Gauss-Newton step on the left
// perturbation (R, t) <- (exp(omega) R, exp(omega) t + v); it stops when a step taken with
// little damping moves t by less than converged_translation_m and turns R by less than
// converged_rotation (radians). Fewer than 6 pairs: the guess back, not converged. A closed-form
// 6x6 Hessian per iteration in place of PCL's BFGS with line searches, which evaluates the cost
// over every pair many times per correspondence set. When nearly undamped steps cycle through 2
// to 4 correspondence sets, the iterate returns to where it was that many steps before and would
// repeat the cycle up to max_iterations: it stops there, converged when the cycle's iterates lie
// within a tenth of the information's sigma floors (closer than the back end can tell).
StageResult RunGicp(const PreparedCloud::Stage& source, const PreparedCloud::Stage& target,
                    const Eigen::Matrix4f& guess, double max_correspondence_m,
                    const RegistrationConfig& config) {
    constexpr int kMinPairs = 6;
    constexpr int kMaxDampingTries = 10;
    constexpr double kStopDamping = 1e-2;  // damping of at most 1 % of the Hessian's diagonal
    const Eigen::Matrix4d T0 = guess.cast<double>();
    Eigen::Matrix3d R = T0.topLeftCorner<3, 3>();
    Eigen::Vector3d t = T0.topRightCorner<3, 1>();
    const auto result = [&](bool converged) {
        Eigen::Matrix4f T = Eigen::Matrix4f::Identity();
        T.topLeftCorner<3, 3>() = R.cast<float>();
        T.topRightCorner<3, 1>() = t.cast<float>();
        return StageResult{T, converged};
    };
    const auto gate = static_cast<float>(max_correspondence_m * max_correspondence_m);
    std::vector<GicpPair> pairs;
    pairs.reserve(source.points.size());
    double lambda = 1e-6;
    GicpCycle cycle;
    Eigen::Matrix<double, 6, 6> H;
    Eigen::Matrix<double, 6, 1> g;
    for (int iteration = 0; iteration < config.max_iterations; ++iteration) {
        const double cost = LinearizeGicp(source, target, R, t, gate, &pairs, &H, &g);
        if (static_cast<int>(pairs.size()) < kMinPairs) {  // lost the overlap: nothing to trust
            R = T0.topLeftCorner<3, 3>();
            t = T0.topRightCorner<3, 1>();
            return result(false);
        }
        bool moved = false;
        for (int attempt = 0; attempt < kMaxDampingTries && !moved; ++attempt) {
            Eigen::Matrix<double, 6, 6> damped = H;
            damped.diagonal() += lambda * H.diagonal().cwiseMax(1e-12);
            const Eigen::Matrix<double, 6, 1> xi = -damped.ldlt().solve(g);
            const Eigen::AngleAxisd turn(xi.head<3>().norm(), xi.head<3>().normalized());
            const Eigen::Matrix3d dR =
                xi.head<3>().norm() > 0.0 ? turn.toRotationMatrix() : Eigen::Matrix3d::Identity();
            const Eigen::Matrix3d R_next = dR * R;
            const Eigen::Vector3d t_next = dR * t + xi.tail<3>();
            if (!(GicpCost(source, target, pairs, R_next, t_next) <= cost)) {
                lambda *= 10.0;
                continue;
            }
            moved = true;
            // A heavily damped step is short wherever it is: only a nearly Gauss-Newton one
            // may end the run.
            const bool undamped = lambda <= kStopDamping;
            lambda = std::max(lambda / 10.0, 1e-12);
            const double moved_m = (t_next - t).norm();
            if (undamped) {
                cycle.Left(R, t);
            } else {
                cycle.Clear();  // a cycle is of nearly Gauss-Newton steps only
            }
            R = R_next;
            t = t_next;
            if (undamped && moved_m < config.converged_translation_m &&
                xi.head<3>().norm() < config.converged_rotation) {
                return result(true);
            }
            // After a damped step the history is empty and no cycle is closed.
            const std::optional<bool> closed = cycle.Closed(
                R, t, config.converged_translation_m, config.converged_rotation,
                0.1 * config.min_translation_sigma_m, 0.1 * config.min_rotation_sigma_rad);
            if (closed) return result(*closed);
        }
        if (!moved) return result(true);  // no damped step lowers the cost: a minimum
    }
    return result(false);
}

Eigen::Isometry3d ToIsometry(const Eigen::Matrix4f& m) {
    const Eigen::Matrix4d md = m.cast<double>();
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::Quaterniond(Eigen::Matrix3d(md.topLeftCorner<3, 3>()))
                     .normalized()
                     .toRotationMatrix();
    T.translation() = md.topRightCorner<3, 1>();
    return T;
}

}  // namespace

void RegistrationConfig::Validate() const {
    if (!(voxel_m > 0)) Invalid("voxel_m", voxel_m, "> 0");
    if (!(max_correspondence_m > 0)) Invalid("max_correspondence_m", max_correspondence_m, "> 0");
    if (!(coarse_voxel_m >= 0)) Invalid("coarse_voxel_m", coarse_voxel_m, ">= 0");
    if (!(coarse_max_correspondence_m > 0)) {
        Invalid("coarse_max_correspondence_m", coarse_max_correspondence_m, "> 0");
    }
    if (max_iterations < 1) Invalid("max_iterations", max_iterations, ">= 1");
    if (!(converged_translation_m > 0)) {
        Invalid("converged_translation_m", converged_translation_m, "> 0");
    }
    if (!(converged_rotation > 0)) Invalid("converged_rotation", converged_rotation, "> 0");
    if (covariance_neighbours < 5) Invalid("covariance_neighbours", covariance_neighbours, ">= 5");
    if (min_points < 6) Invalid("min_points", min_points, ">= 6");
    if (!(inlier_distance_m > 0)) Invalid("inlier_distance_m", inlier_distance_m, "> 0");
    if (!(min_fitness >= 0 && min_fitness <= 1)) Invalid("min_fitness", min_fitness, "in [0, 1]");
    if (!(min_translation_eigen_ratio >= 0 && min_translation_eigen_ratio < 1)) {
        Invalid("min_translation_eigen_ratio", min_translation_eigen_ratio, "in [0, 1)");
    }
    if (!(min_translation_sigma_m > 0)) {
        Invalid("min_translation_sigma_m", min_translation_sigma_m, "> 0");
    }
    if (!(min_rotation_sigma_rad > 0)) {
        Invalid("min_rotation_sigma_rad", min_rotation_sigma_rad, "> 0");
    }
}

Eigen::Isometry3d YawGuess(double yaw_rad) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    return T;
}

PreparedCloud::PreparedCloud(const PointCloud& cloud, const RegistrationConfig& config,
                             bool as_target)
    : voxel_m_(config.voxel_m),
      coarse_voxel_m_(config.coarse_voxel_m),
      covariance_neighbours_(config.covariance_neighbours),
      min_points_(config.min_points),
      as_target_(as_target) {
    config.Validate();
    fine_ = MakeStage(cloud, config.voxel_m, config, /*normals=*/as_target);
    if (config.coarse_voxel_m > 0 && fine_->tree) {
        coarse_ = MakeStage(cloud, config.coarse_voxel_m, config, /*normals=*/false);
        if (!coarse_->tree) coarse_.reset();
    }
}

PreparedCloud::~PreparedCloud() = default;

int PreparedCloud::NumFinePoints() const { return static_cast<int>(fine_->points.size()); }

bool PreparedCloud::PreparedFor(const RegistrationConfig& config) const {
    return voxel_m_ == config.voxel_m && coarse_voxel_m_ == config.coarse_voxel_m &&
           covariance_neighbours_ == config.covariance_neighbours &&
           min_points_ == config.min_points;
}

RegistrationResult RegisterScans(const PointCloud& source, const PointCloud& target,
                                 const Eigen::Isometry3d& T_target_source_guess,
                                 const RegistrationConfig& config) {
    return RegisterScans(PreparedCloud(source, config, /*as_target=*/false),
                         PreparedCloud(target, config), T_target_source_guess, config);
}

RegistrationResult RegisterScans(const PreparedCloud& source, const PreparedCloud& target,
                                 const Eigen::Isometry3d& T_target_source_guess,
                                 const RegistrationConfig& config) {
    config.Validate();
    CERTISLAM_CHECK(source.PreparedFor(config) && target.PreparedFor(config) &&
                    target.PreparedAsTarget());
    RegistrationResult result;
    result.T_target_source = T_target_source_guess;
    result.num_source_points = source.NumFinePoints();
    result.num_target_points = target.NumFinePoints();
    if (result.num_source_points < config.min_points ||
        result.num_target_points < config.min_points) {
        result.status = RegistrationResult::Status::kTooFewPoints;
        return result;
    }
    Eigen::Matrix4f T = T_target_source_guess.matrix().cast<float>();
    if (source.Coarse() && target.Coarse()) {  // coarse stage: wide gate absorbs SC's metres
        // Kept at the iteration cap too, as PCL's GICP kept it (fewer than 6 pairs: the guess).
        T = RunGicp(*source.Coarse(), *target.Coarse(), T, config.coarse_max_correspondence_m,
                    config)
                .T_target_source;
    }
    const StageResult fine =
        RunGicp(source.Fine(), target.Fine(), T, config.max_correspondence_m, config);
    result.converged = fine.converged;
    result.T_target_source = ToIsometry(fine.T_target_source);
    const RegistrationResult::Status quality =
        EvaluateAlignment(source.Fine().points, target.Fine().points, *target.Fine().tree,
                          target.Fine().normals, config, result);
    result.status = result.converged ? quality : RegistrationResult::Status::kNotConverged;
    return result;
}

}  // namespace certislam::slam
