// Scan-to-scan registration: the settings check, the yaw guess, clouds prepared once (trees,
// normals, GICP covariances) and RegisterScans with PCL's GICP
// (the project's only PCL registration translation unit: no PCL header leaves this file).
#include "slam/frontend/registration.h"

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/registration/gicp.h>
#include <pcl/search/kdtree.h>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <memory>
#include <stdexcept>
#include <string>

#include "slam/core/check.h"
#include "slam/frontend/downsample.h"
#include "slam/frontend/point_kdtree.h"
#include "slam/frontend/registration_quality.h"

namespace certislam::slam {
namespace {

[[noreturn]] void Invalid(const std::string& field, double value, const std::string& rule) {
    throw std::invalid_argument("RegistrationConfig." + field + " = " + std::to_string(value) +
                                ": must be " + rule);
}

using PclCloud = pcl::PointCloud<pcl::PointXYZ>;

PclCloud::Ptr ToPcl(const PointCloud& cloud) {
    auto out = std::make_shared<PclCloud>();
    out->resize(cloud.size());
    for (std::size_t i = 0; i < cloud.size(); ++i) {
        (*out)[i].getVector3fMap() = cloud[i];
    }
    return out;
}

// PCL's search interface answered by the project's nanoflann tree. GICP asks one point at a time;
// FLANN's knnSearch opens an OpenMP parallel region per call, whose thread wake-ups (futex) cost
// more than the query itself.
class NanoflannSearch : public pcl::search::KdTree<pcl::PointXYZ> {
  public:
    void setInputCloud(const PointCloudConstPtr& cloud,
                       const pcl::IndicesConstPtr& indices = pcl::IndicesConstPtr()) override {
        if (indices && !indices->empty()) {
            throw std::invalid_argument("NanoflannSearch: index subsets are not supported");
        }
        input_ = cloud;
        indices_ = indices;
        points_.resize(cloud->size());
        for (std::size_t i = 0; i < cloud->size(); ++i) points_[i] = (*cloud)[i].getVector3fMap();
        nano_ = std::make_unique<PointKdTree>(points_);
    }

    /// The tree over the cloud last given to setInputCloud.
    const PointKdTree& Tree() const { return *nano_; }

    int nearestKSearch(const pcl::PointXYZ& point, int k, pcl::Indices& k_indices,
                       std::vector<float>& k_sqr_distances) const override {
        thread_local std::vector<std::size_t> found;  // GICP asks once per point and iteration
        nano_->Knn(point.getVector3fMap(), static_cast<std::size_t>(std::max(k, 0)), found,
                   k_sqr_distances);
        k_indices.assign(found.begin(), found.end());
        return static_cast<int>(found.size());
    }

    int radiusSearch(const pcl::PointXYZ& point, double radius, pcl::Indices& k_indices,
                     std::vector<float>& k_sqr_distances, unsigned int max_nn) const override {
        std::vector<std::pair<std::size_t, float>> found;
        nano_->Within(point.getVector3fMap(), static_cast<float>(radius * radius), found);
        if (max_nn > 0 && found.size() > max_nn) found.resize(max_nn);
        k_indices.resize(found.size());
        k_sqr_distances.resize(found.size());
        for (std::size_t i = 0; i < found.size(); ++i) {
            k_indices[i] = static_cast<pcl::index_t>(found[i].first);
            k_sqr_distances[i] = found[i].second;
        }
        return static_cast<int>(found.size());
    }

  private:
    slam::PointCloud points_;  // the tree refers to these by address
    std::unique_ptr<PointKdTree> nano_;
};

using Gicp = pcl::GeneralizedIterativeClosestPoint<pcl::PointXYZ, pcl::PointXYZ>;

// GICP's plane-to-plane covariance (Segal et al. 2009, Sec. III-B) of the points `indices`, with
// PCL's computeCovariances arithmetic (raw moments of float products, so registrations stay
// those of PCL's GICP) and the smallest-|eigenvalue| direction set to PCL's gicp_epsilon_
// default, the others to 1: an eigen-decomposition in place of PCL's SVD (the same matrix but in
// near-degenerate neighbourhoods, where either direction is arbitrary).
Eigen::Matrix3d PclPlaneCovariance(const PointCloud& cloud,
                                   const std::vector<std::size_t>& indices) {
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
    PointCloud points;                      ///< downsampled at the stage's voxel
    PclCloud::Ptr pcl;                      ///< the same points for PCL
    std::shared_ptr<NanoflannSearch> tree;  ///< over pcl (null below min_points)
    std::vector<Eigen::Vector3d> normals;   ///< PlaneNormal of each k-NN (fine stage only)
    Gicp::MatricesVectorPtr covariances;    ///< GICP's, per point (null below min_points)
};

namespace {

// Downsampled points; their tree, covariances and (with `normals`) planes only when registration
// will use them.
std::unique_ptr<PreparedCloud::Stage> MakeStage(const PointCloud& cloud, double voxel_m,
                                                const RegistrationConfig& config, bool normals) {
    auto stage = std::make_unique<PreparedCloud::Stage>();
    stage->points = VoxelDownsample(cloud, voxel_m);
    if (static_cast<int>(stage->points.size()) < config.min_points) return stage;
    stage->pcl = ToPcl(stage->points);
    stage->tree = std::make_shared<NanoflannSearch>();
    stage->tree->setInputCloud(stage->pcl);
    // One k-NN pass for GICP's covariances and the quality test's planes.
    stage->covariances = std::make_shared<Gicp::MatricesVector>();
    stage->covariances->reserve(stage->points.size());
    if (normals) stage->normals.reserve(stage->points.size());
    std::vector<std::size_t> indices;
    std::vector<float> squared;
    for (const Eigen::Vector3f& p : stage->points) {
        stage->tree->Tree().Knn(p, static_cast<std::size_t>(config.covariance_neighbours), indices,
                                squared);
        stage->covariances->push_back(PclPlaneCovariance(stage->points, indices));
        if (normals) stage->normals.push_back(PlaneNormal(stage->points, indices));
    }
    return stage;
}

// One GICP run (Segal et al. 2009) from `guess` on prepared stages (trees and covariances kept).
StageResult RunGicp(const PreparedCloud::Stage& source, const PreparedCloud::Stage& target,
                    const Eigen::Matrix4f& guess, double max_correspondence_m,
                    const RegistrationConfig& config) {
    Gicp gicp;
    gicp.setSearchMethodSource(source.tree, /*force_no_recompute=*/true);
    gicp.setSearchMethodTarget(target.tree, /*force_no_recompute=*/true);
    gicp.setInputSource(source.pcl);  // resets the covariances: set them after
    gicp.setSourceCovariances(source.covariances);
    gicp.setInputTarget(target.pcl);
    gicp.setTargetCovariances(target.covariances);
    gicp.setMaxCorrespondenceDistance(max_correspondence_m);
    gicp.setMaximumIterations(config.max_iterations);
    gicp.setCorrespondenceRandomness(config.covariance_neighbours);
    gicp.setTransformationEpsilon(config.converged_translation_m);
    gicp.setRotationEpsilon(config.converged_rotation);
    PclCloud aligned;
    gicp.align(aligned, guess);
    return {gicp.getFinalTransformation(), gicp.hasConverged()};
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
        const StageResult coarse = RunGicp(*source.Coarse(), *target.Coarse(), T,
                                           config.coarse_max_correspondence_m, config);
        if (coarse.converged) T = coarse.T_target_source;
    }
    const StageResult fine =
        RunGicp(source.Fine(), target.Fine(), T, config.max_correspondence_m, config);
    result.converged = fine.converged;
    result.T_target_source = ToIsometry(fine.T_target_source);
    const RegistrationResult::Status quality =
        EvaluateAlignment(source.Fine().points, target.Fine().points, target.Fine().tree->Tree(),
                          target.Fine().normals, config, result);
    result.status = result.converged ? quality : RegistrationResult::Status::kNotConverged;
    return result;
}

}  // namespace certislam::slam
