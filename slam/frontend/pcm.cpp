// Pairwise consistency maximization: Mahalanobis consistency and exact maximum clique.
#include "slam/frontend/pcm.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>
#include <string>
#include <utility>

#include "slam/core/check.h"
#include "slam/core/se3.h"

namespace certislam::slam {
namespace {

[[noreturn]] void Invalid(const std::string& field, double value, const std::string& rule) {
    throw std::invalid_argument("PcmConfig." + field + " = " + std::to_string(value) +
                                ": must be " + rule);
}

// (translation, rotation vector) of a pose: the SE(3) log to first order in the rotation.
Vector6 Error(const Eigen::Isometry3d& E) {
    const Eigen::AngleAxisd aa(E.rotation());
    Vector6 e;
    e << E.translation(), aa.angle() * aa.axis();
    return e;
}

Matrix6 Covariance(const Information6& information) {
    return information.ldlt().solve(Matrix6::Identity());
}

// Covariance of robot r's odometry between keyframes k0 and k1.
Matrix6 OdometryCovariance(const std::vector<std::vector<double>>& travelled, int r, int k0, int k1,
                           const PcmConfig& config) {
    const double d = std::abs(travelled[r][k1] - travelled[r][k0]);
    const double st = config.odom_min_sigma_t_m + config.odom_translation_sigma_per_m * d;
    const double sr = config.odom_min_sigma_r_rad + config.odom_rotation_sigma_per_m * d;
    Vector6 diag;
    diag << st * st, st * st, st * st, sr * sr, sr * sr, sr * sr;
    return diag.asDiagonal();
}

double Mahalanobis2(const Vector6& e, const Matrix6& covariance) {
    return e.dot(covariance.ldlt().solve(e));
}

// The measurement seen from b to a: T_b_a with its information (right perturbation).
PcmMeasurement Inverted(const PcmMeasurement& m) {
    const Matrix6 ad = Adjoint(m.T_a_b);  // Sigma_inv = Ad Sigma Ad^T
    const Matrix6 ad_inv = ad.inverse();
    return {m.b, m.a, m.T_a_b.inverse(), ad_inv.transpose() * m.information * ad_inv};
}

}  // namespace

void PcmConfig::Validate() const {
    if (!(chi2_threshold > 0)) Invalid("chi2_threshold", chi2_threshold, "> 0");
    if (!(odom_translation_sigma_per_m >= 0)) {
        Invalid("odom_translation_sigma_per_m", odom_translation_sigma_per_m, ">= 0");
    }
    if (!(odom_rotation_sigma_per_m >= 0)) {
        Invalid("odom_rotation_sigma_per_m", odom_rotation_sigma_per_m, ">= 0");
    }
    if (!(odom_min_sigma_t_m > 0)) Invalid("odom_min_sigma_t_m", odom_min_sigma_t_m, "> 0");
    if (!(odom_min_sigma_r_rad > 0)) Invalid("odom_min_sigma_r_rad", odom_min_sigma_r_rad, "> 0");
    if (min_clique_size < 1) Invalid("min_clique_size", min_clique_size, ">= 1");
    if (max_branch_nodes < 1) {
        Invalid("max_branch_nodes", static_cast<double>(max_branch_nodes), ">= 1");
    }
}

std::vector<std::vector<double>> TravelledDistances(
    const std::vector<std::vector<Eigen::Isometry3d>>& odometry) {
    std::vector<std::vector<double>> out(odometry.size());
    for (size_t r = 0; r < odometry.size(); ++r) {
        double sum = 0.0;
        for (size_t k = 0; k < odometry[r].size(); ++k) {
            if (k > 0) {
                sum += (odometry[r][k].translation() - odometry[r][k - 1].translation()).norm();
            }
            out[r].push_back(sum);
        }
    }
    return out;
}

double PairwiseMahalanobis2(const PcmMeasurement& i, const PcmMeasurement& j,
                            const std::vector<std::vector<Eigen::Isometry3d>>& odometry,
                            const std::vector<std::vector<double>>& travelled,
                            const PcmConfig& config) {
    CERTISLAM_CHECK(i.a.robot == j.a.robot && i.b.robot == j.b.robot);
    const int ra = i.a.robot, rb = i.b.robot;
    const Eigen::Isometry3d T_bi_bj = odometry[rb][i.b.index].inverse() * odometry[rb][j.b.index];
    const Eigen::Isometry3d T_ai_aj = odometry[ra][i.a.index].inverse() * odometry[ra][j.a.index];
    // E = (T_ai_aj T_aj_bj)^-1 (T_ai_bi T_bi_bj): identity when both loops agree with odometry.
    const Eigen::Isometry3d E = (T_ai_aj * j.T_a_b).inverse() * (i.T_a_b * T_bi_bj);
    const Matrix6 ad_e_inv = Adjoint(E.inverse());
    const Matrix6 J1 = Adjoint(T_bi_bj.inverse());              // loop i
    const Matrix6 J3 = -ad_e_inv;                               // loop j
    const Matrix6 J4 = -ad_e_inv * Adjoint(j.T_a_b.inverse());  // odometry of a
    const Matrix6 cov =
        J1 * Covariance(i.information) * J1.transpose() +
        OdometryCovariance(travelled, rb, i.b.index, j.b.index, config) +
        J3 * Covariance(j.information) * J3.transpose() +
        J4 * OdometryCovariance(travelled, ra, i.a.index, j.a.index, config) * J4.transpose();
    return Mahalanobis2(Error(E), cov);
}

PcmResult RejectOutliersPcm(const std::vector<PcmMeasurement>& measurements,
                            const std::vector<std::vector<Eigen::Isometry3d>>& odometry,
                            const PcmConfig& config) {
    config.Validate();
    PcmResult result;
    result.inlier.assign(measurements.size(), false);
    const auto travelled = TravelledDistances(odometry);
    std::map<std::pair<int, int>, std::vector<int>> groups;  // (ra, rb) -> measurement indices
    std::vector<PcmMeasurement> oriented;
    for (size_t k = 0; k < measurements.size(); ++k) {
        const PcmMeasurement& m = measurements[k];
        CERTISLAM_CHECK(m.a.robot >= 0 && m.a.robot < static_cast<int>(odometry.size()));
        CERTISLAM_CHECK(m.b.robot >= 0 && m.b.robot < static_cast<int>(odometry.size()));
        oriented.push_back(m.a.robot <= m.b.robot ? m : Inverted(m));
        const PcmMeasurement& o = oriented.back();
        if (o.a.robot == o.b.robot && config.check_intra_against_odometry) {
            const Eigen::Isometry3d T_odom =
                odometry[o.a.robot][o.a.index].inverse() * odometry[o.b.robot][o.b.index];
            const Eigen::Isometry3d E = T_odom.inverse() * o.T_a_b;
            const Matrix6 J = -Adjoint(E.inverse());
            const Matrix6 cov =
                Covariance(o.information) +
                J * OdometryCovariance(travelled, o.a.robot, o.a.index, o.b.index, config) *
                    J.transpose();
            if (Mahalanobis2(Error(E), cov) > config.chi2_threshold) {
                ++result.rejected_by_odometry;
                continue;
            }
        }
        groups[{o.a.robot, o.b.robot}].push_back(static_cast<int>(k));
    }
    for (const auto& [pair, members] : groups) {
        ++result.groups;
        const int n = static_cast<int>(members.size());
        std::vector<std::vector<int>> adjacency(n);
        for (int u = 0; u < n; ++u) {
            for (int v = u + 1; v < n; ++v) {
                const double m2 = PairwiseMahalanobis2(oriented[members[u]], oriented[members[v]],
                                                       odometry, travelled, config);
                if (m2 <= config.chi2_threshold) {
                    adjacency[u].push_back(v);
                    adjacency[v].push_back(u);
                    ++result.consistent_pairs;
                }
            }
        }
        std::int64_t nodes = 0;
        bool exact = true;
        const auto clique = MaximumClique(adjacency, config.max_branch_nodes, &nodes, &exact);
        result.branch_nodes += nodes;
        if (!exact) result.status = PcmResult::Status::kTruncated;
        if (static_cast<int>(clique.size()) < config.min_clique_size) continue;
        for (const int u : clique) result.inlier[members[u]] = true;
    }
    return result;
}

}  // namespace certislam::slam
