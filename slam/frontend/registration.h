// Loop-closure verification: GICP registration of a candidate pair seeded with the Scan Context
// yaw, with fitness, a degeneracy check and an information matrix for the back end.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <memory>

#include "slam/core/keyframe.h"

namespace certislam::slam {

/// Settings of scan-to-scan registration and of the acceptance tests.
struct RegistrationConfig {
    double voxel_m = 0.2;                      ///< fine-stage voxel size, > 0
    double max_correspondence_m = 1.0;         ///< fine-stage GICP correspondence gate, > 0
    double coarse_voxel_m = 1.0;               ///< coarse stage voxel (0 = no coarse stage)
    double coarse_max_correspondence_m = 5.0;  ///< coarse-stage gate, > 0 (absorbs SC's metres)
    int max_iterations = 50;                   ///< GICP iterations per stage, >= 1
    /// GICP stops once a nearly undamped step moves the translation less than this and turns
    /// the rotation by less than converged_rotation radians (far below registration noise:
    /// see the sigma floors); a stage that has not stopped within max_iterations has not
    /// converged (kNotConverged). One whose nearly undamped steps cycle through 2 to 4
    /// correspondence sets (the iterate back where it was that many steps before) stops there,
    /// converged when the cycle's iterates lie within a tenth of min_translation_sigma_m and
    /// min_rotation_sigma_rad. Metres, > 0.
    double converged_translation_m = 1e-4;
    double converged_rotation = 1e-5;           ///< see converged_translation_m, > 0
    int covariance_neighbours = 20;             ///< k of GICP's local covariances, >= 5
    int min_points = 100;                       ///< fewer points after downsampling: rejected
    double inlier_distance_m = 0.5;             ///< fitness gate on nearest-neighbour distance
    double min_fitness = 0.3;                   ///< reject below this inlier fraction, [0, 1]
    double min_translation_eigen_ratio = 0.02;  ///< reject when lambda_min/lambda_max of the
                                                ///< Hessian's translation block is below, [0, 1)
    double min_translation_sigma_m = 0.05;      ///< covariance floor (unmodelled errors), > 0
    double min_rotation_sigma_rad = 0.005;      ///< covariance floor, > 0

    /// Throws std::invalid_argument naming the field, its value and the rule.
    void Validate() const;
};

/// 6x6 information of a relative pose, ordered (tx ty tz rx ry rz), for a perturbation on the
/// right: T = T_hat * exp(delta) (delta in the source frame), as g2o's EDGE_SE3 uses it.
using Information6 = Eigen::Matrix<double, 6, 6>;

/// How registration ended and what it found.
struct RegistrationResult {
    enum class Status {
        kAccepted,      ///< converged, fit and well-conditioned: a usable loop closure
        kTooFewPoints,  ///< a cloud had fewer than min_points after downsampling
        kNotConverged,  ///< GICP did not converge
        kLowFitness,    ///< inlier fraction below min_fitness
        kDegenerate,    ///< translation poorly constrained (corridor, tunnel, open field)
    };
    Status status = Status::kTooFewPoints;                              ///< verdict
    Eigen::Isometry3d T_target_source = Eigen::Isometry3d::Identity();  ///< maps source points
                                                                        ///< into the target
    Information6 information = Information6::Zero();  ///< see Information6 (floors applied)
    double kappa = 0.0;          ///< rotation weight, SE-Sync convention: 3 / (2 tr(Omega_RR^-1))
    double tau = 0.0;            ///< translation weight: 3 / tr(Omega_tt^-1)
    bool converged = false;      ///< GICP's own convergence flag (fine stage)
    double fitness = 0.0;        ///< fraction of source points with a target point within
                                 ///< inlier_distance_m after alignment, [0, 1]
    double inlier_rmse_m = 0.0;  ///< RMS point-to-plane residual of those inliers
    double translation_eigen_ratio = 0.0;  ///< lambda_min / lambda_max of sum n n^T
    Eigen::Vector3d translation_eigenvalues = Eigen::Vector3d::Zero();  ///< ascending, per point
    int num_source_points = 0;                                          ///< after downsampling
    int num_target_points = 0;                                          ///< after downsampling

    /// True for Status::kAccepted.
    bool accepted() const { return status == Status::kAccepted; }
};

/// A pure-yaw initial guess (e.g. ScanContextMatch::yaw_rad for query = source).
Eigen::Isometry3d YawGuess(double yaw_rad);

/// A cloud made ready for registration once (downsampled for both stages, search trees, GICP's
/// local covariances), so a keyframe that is in several candidates is prepared only once.
class PreparedCloud {
  public:
    /// Prepares `cloud` for RegisterScans with `config` (validated here). `as_target`: also the
    /// local planes the quality test reads at a target's points (a source needs none).
    PreparedCloud(const PointCloud& cloud, const RegistrationConfig& config, bool as_target = true);
    ~PreparedCloud();
    PreparedCloud(const PreparedCloud&) = delete;
    PreparedCloud& operator=(const PreparedCloud&) = delete;

    struct Stage;  ///< one stage's cloud, tree and covariances (registration.cpp)
    /// The fine stage's data.
    const Stage& Fine() const { return *fine_; }
    /// The coarse stage's data; null without a coarse stage or with fewer than min_points.
    const Stage* Coarse() const { return coarse_.get(); }
    /// Points after the fine stage's downsampling.
    int NumFinePoints() const;
    /// True when prepared with the settings RegisterScans uses from `config`.
    bool PreparedFor(const RegistrationConfig& config) const;
    /// True when prepared as a target (with its local planes).
    bool PreparedAsTarget() const { return as_target_; }

  private:
    double voxel_m_ = 0.0, coarse_voxel_m_ = 0.0;
    int covariance_neighbours_ = 0, min_points_ = 0;
    bool as_target_ = true;
    std::unique_ptr<Stage> fine_, coarse_;
};

/// Registers `source` onto `target` (both in their sensor frames) from `T_target_source_guess`:
/// voxel downsampling, a coarse then a fine GICP stage, then fitness, point-to-plane Hessian,
/// degeneracy check and information. Never throws on bad geometry: the status says.
RegistrationResult RegisterScans(const PointCloud& source, const PointCloud& target,
                                 const Eigen::Isometry3d& T_target_source_guess,
                                 const RegistrationConfig& config);

/// RegisterScans on clouds prepared with `config`, `target` as a target (the same result,
/// without preparing again).
RegistrationResult RegisterScans(const PreparedCloud& source, const PreparedCloud& target,
                                 const Eigen::Isometry3d& T_target_source_guess,
                                 const RegistrationConfig& config);

}  // namespace certislam::slam
