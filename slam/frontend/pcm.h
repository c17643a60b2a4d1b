// Pairwise consistency maximization (Mangelson et al., ICRA 2018): loop closures between the
// same two robots are tested pairwise for consistency with odometry by a Mahalanobis distance
// against a chi-square threshold; the exact maximum clique of the consistency graph is kept.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "slam/core/pose_graph.h"
#include "slam/frontend/max_clique.h"
#include "slam/frontend/registration.h"

namespace certislam::slam {

/// Settings of the consistency test and of the clique search.
struct PcmConfig {
    double chi2_threshold = 16.81;  ///< squared Mahalanobis gate; chi-square 6 dof at 99 %, > 0
    /// Odometry uncertainty grows with the distance travelled d between two keyframes:
    /// sigma_t = min_sigma_t + translation_sigma_per_m * d (LIO drift: a slow yaw-rate bias
    /// makes the lateral error grow with d, so sigma grows linearly, not with sqrt(d)).
    double odom_translation_sigma_per_m = 0.01;  ///< >= 0 (LIO: ~1 % drift)
    double odom_rotation_sigma_per_m = 5e-4;     ///< rad per metre travelled, >= 0
    double odom_min_sigma_t_m = 0.1;             ///< > 0
    double odom_min_sigma_r_rad = 0.01;          ///< > 0
    int min_clique_size = 2;  ///< a group whose maximum clique is smaller keeps nothing, >= 1
    bool check_intra_against_odometry = true;  ///< a loop within one robot must also agree
                                               ///< with that robot's odometry between a and b
    /// Clique search budget in MaximumClique's work units (a branch node and its candidates),
    /// >= 1 (a loop matcher, which searches after every verified batch, sets a smaller one).
    std::int64_t max_branch_nodes = 50'000'000;

    /// Throws std::invalid_argument naming the field, its value and the rule.
    void Validate() const;
};

/// One loop-closure measurement to test: T_a_b with its information (Information6 ordering,
/// right perturbation, as RegisterScans gives it).
struct PcmMeasurement {
    PoseId a;                                                 ///< tail keyframe
    PoseId b;                                                 ///< head keyframe
    Eigen::Isometry3d T_a_b = Eigen::Isometry3d::Identity();  ///< pose of b in a's frame
    Information6 information = Information6::Identity();      ///< of T_a_b, positive definite
};

/// What PCM kept.
struct PcmResult {
    enum class Status {
        kExact,      ///< every group's maximum clique was found exactly
        kTruncated,  ///< some clique search hit max_branch_nodes: best clique found so far kept
    };
    Status status = Status::kExact;  ///< verdict of the clique search
    std::vector<bool> inlier;        ///< per measurement: kept
    int groups = 0;                  ///< robot pairs (ra <= rb) with measurements
    int consistent_pairs = 0;        ///< edges of the consistency graphs
    int rejected_by_odometry = 0;    ///< intra-robot loops that disagree with odometry alone
    std::int64_t branch_nodes = 0;   ///< clique-search work (MaximumClique's units), all groups
};

/// Squared Mahalanobis distance of the cycle loop i -> odometry of b -> loop j^-1 -> odometry of
/// a (first-order covariance propagation of both loops and both odometry segments). `i` and `j`
/// must join the same two robots in the same order (i.a.robot == j.a.robot, same for b).
/// `odometry[r][k]` is T_odom_sensor of robot r's keyframe k; `travelled[r][k]` the distance
/// along robot r's odometry up to keyframe k.
double PairwiseMahalanobis2(const PcmMeasurement& i, const PcmMeasurement& j,
                            const std::vector<std::vector<Eigen::Isometry3d>>& odometry,
                            const std::vector<std::vector<double>>& travelled,
                            const PcmConfig& config);

/// Cumulative travelled distance along each robot's odometry poses.
std::vector<std::vector<double>> TravelledDistances(
    const std::vector<std::vector<Eigen::Isometry3d>>& odometry);

/// Runs PCM per robot pair: consistency graph, exact maximum clique, inliers out. Loops are
/// oriented so that a.robot <= b.robot before grouping (the inverse measurement is used).
PcmResult RejectOutliersPcm(const std::vector<PcmMeasurement>& measurements,
                            const std::vector<std::vector<Eigen::Isometry3d>>& odometry,
                            const PcmConfig& config);

}  // namespace certislam::slam
