// Robot-held rows of S and a Lanczos iteration whose products exchange only public entries.
#include "certify/distributed/distributed_certificate.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <map>
#include <random>
#include <stdexcept>
#include <string>

#include "slam/core/check.h"

namespace certislam::certify {
namespace {

using Segments = std::vector<Eigen::VectorXd>;

constexpr double kBreakdown = 1e-300;  ///< beta below this: the Krylov space is invariant

double Dot(const Segments& a, const Segments& b) {
    double s = 0.0;
    for (size_t k = 0; k < a.size(); ++k) s += a[k].dot(b[k]);
    return s;
}

void Axpy(double alpha, const Segments& x, Segments* y) {
    for (size_t k = 0; k < x.size(); ++k) (*y)[k] += alpha * x[k];
}

// The team's product S v: every robot publishes its public entries, then multiplies its rows.
class Team {
  public:
    explicit Team(const std::vector<CertificateRows>& robots) : robots_(robots) {
        for (size_t k = 0; k < robots.size(); ++k) {
            for (size_t p = 0; p < robots[k].public_poses.size(); ++p) {
                where_[robots[k].public_poses[p]] = {static_cast<int>(k), static_cast<int>(p)};
            }
        }
    }

    Segments Multiply(const Segments& v, DistributedEigenResult* stats) const {
        Segments messages(robots_.size());
        for (size_t k = 0; k < robots_.size(); ++k) {
            messages[k] = PublicEntries(robots_[k], v[k]);
            stats->entries_exchanged += static_cast<double>(messages[k].size());
        }
        Segments out(robots_.size());
        for (size_t k = 0; k < robots_.size(); ++k) {
            const CertificateRows& rows = robots_[k];
            const int b = rows.d + 1;
            Eigen::VectorXd nbr(b * static_cast<int>(rows.neighbor_poses.size()));
            for (size_t p = 0; p < rows.neighbor_poses.size(); ++p) {
                const auto [owner, index] = where_.at(rows.neighbor_poses[p]);
                nbr.segment(b * p, b) = messages[owner].segment(b * index, b);
            }
            out[k] = MultiplyRows(rows, v[k], nbr);
        }
        ++stats->products;
        return out;
    }

    Segments Random(std::uint64_t seed) const {
        std::mt19937_64 rng(seed);
        std::normal_distribution<double> normal;
        Segments v(robots_.size());
        for (size_t k = 0; k < robots_.size(); ++k) {
            v[k].resize(robots_[k].own.rows());
            for (Eigen::Index i = 0; i < v[k].size(); ++i) v[k][i] = normal(rng);
        }
        return v;
    }

  private:
    const std::vector<CertificateRows>& robots_;
    std::map<int, std::pair<int, int>> where_;  // public pose -> (robot, index in its list)
};

}  // namespace

CertificateRows MakeCertificateRows(const Eigen::SparseMatrix<double>& Q, const Eigen::MatrixXd& X,
                                    int d, const slam::Partition& partition, int robot) {
    CERTISLAM_CHECK(robot >= 0 && robot < partition.num_robots());
    CERTISLAM_CHECK(X.cols() == Q.cols() && Q.rows() == Q.cols());
    CertificateRows rows;
    rows.robot = robot;
    rows.d = d;
    rows.first_pose = partition.begin[robot];
    rows.poses = partition.size(robot);
    const int b = d + 1;
    const int c0 = b * rows.first_pose;
    const int cols = b * rows.poses;
    std::map<int, int> nbr;  // neighbour global pose -> compact index
    std::vector<bool> is_public(rows.poses, false);
    Eigen::MatrixXd XQ = Eigen::MatrixXd::Zero(X.rows(), cols);  // (X Q)[:, own columns]
    for (int c = 0; c < cols; ++c) {
        for (Eigen::SparseMatrix<double>::InnerIterator it(Q, c0 + c); it; ++it) {
            const int row = static_cast<int>(it.row());
            XQ.col(c) += it.value() * X.col(row);
            if (row < c0 || row >= c0 + cols) {
                nbr.emplace(row / b, 0);
                is_public[c / b] = true;
            }
        }
    }
    for (auto& [pose, index] : nbr) {
        index = static_cast<int>(rows.neighbor_poses.size());
        rows.neighbor_poses.push_back(pose);
    }
    for (int k = 0; k < rows.poses; ++k) {
        if (is_public[k]) rows.public_poses.push_back(rows.first_pose + k);
    }
    std::vector<Eigen::Triplet<double>> own, cross;
    for (int c = 0; c < cols; ++c) {  // S symmetric: row c of S is column c0 + c of Q
        for (Eigen::SparseMatrix<double>::InnerIterator it(Q, c0 + c); it; ++it) {
            const int row = static_cast<int>(it.row());
            if (row >= c0 && row < c0 + cols) {
                own.emplace_back(c, row - c0, it.value());
            } else {
                cross.emplace_back(c, nbr[row / b] * b + row % b, it.value());
            }
        }
    }
    for (int i = 0; i < rows.poses; ++i) {
        const int c = b * i;
        const Eigen::MatrixXd P = XQ.middleCols(c, d).transpose() * X.middleCols(c0 + c, d);
        const Eigen::MatrixXd lambda = 0.5 * (P + P.transpose());
        rows.trace_lambda += lambda.trace();
        for (int r = 0; r < d; ++r) {
            for (int s = 0; s < d; ++s) own.emplace_back(c + r, c + s, -lambda(r, s));
        }
    }
    rows.own.resize(cols, cols);
    rows.own.setFromTriplets(own.begin(), own.end());
    rows.nbr.resize(cols, b * static_cast<int>(rows.neighbor_poses.size()));
    rows.nbr.setFromTriplets(cross.begin(), cross.end());
    return rows;
}

Eigen::VectorXd PublicEntries(const CertificateRows& rows, const Eigen::VectorXd& v_own) {
    const int b = rows.d + 1;
    Eigen::VectorXd out(b * static_cast<int>(rows.public_poses.size()));
    for (size_t p = 0; p < rows.public_poses.size(); ++p) {
        out.segment(b * p, b) = v_own.segment(b * (rows.public_poses[p] - rows.first_pose), b);
    }
    return out;
}

Eigen::VectorXd MultiplyRows(const CertificateRows& rows, const Eigen::VectorXd& v_own,
                             const Eigen::VectorXd& v_neighbors) {
    Eigen::VectorXd y = rows.own * v_own;
    if (rows.nbr.cols() > 0) y += rows.nbr * v_neighbors;
    return y;
}

void DistributedEigenConfig::Validate() const {
    if (max_krylov < 2) {
        throw std::invalid_argument(
            "DistributedEigenConfig.max_krylov = " + std::to_string(max_krylov) + ": must be >= 2");
    }
    if (!(tolerance > 0.0)) {
        throw std::invalid_argument(
            "DistributedEigenConfig.tolerance = " + std::to_string(tolerance) + ": must be > 0");
    }
    if (check_every < 1) {
        throw std::invalid_argument("DistributedEigenConfig.check_every = " +
                                    std::to_string(check_every) + ": must be >= 1");
    }
}

DistributedEigenResult DistributedMinEigenpair(const std::vector<CertificateRows>& robots,
                                               const DistributedEigenConfig& config) {
    config.Validate();
    CERTISLAM_CHECK(!robots.empty());
    DistributedEigenResult result;
    const Team team(robots);
    std::vector<Segments> basis;
    Segments q = team.Random(config.seed);
    const double norm0 = std::sqrt(Dot(q, q));
    for (auto& s : q) s /= norm0;
    ++result.scalar_reductions;
    std::vector<double> alpha, beta;
    Eigen::VectorXd ritz;  // coefficients of the Ritz vector in the basis
    bool done = false;
    for (int j = 0; j < config.max_krylov && !done; ++j) {
        basis.push_back(q);
        Segments w = team.Multiply(q, &result);
        alpha.push_back(Dot(q, w));
        ++result.scalar_reductions;
        for (const Segments& u : basis) Axpy(-Dot(u, w), u, &w);  // full reorthogonalisation,
        for (const Segments& u : basis) Axpy(-Dot(u, w), u, &w);  // twice ("twice is enough")
        result.scalar_reductions += 2;  // each pass: all its dots in one reduction
        const double b = std::sqrt(Dot(w, w));
        ++result.scalar_reductions;
        const int m = static_cast<int>(alpha.size());
        const bool breakdown = b < kBreakdown || m == config.max_krylov;
        if (breakdown || m % config.check_every == 0) {
            Eigen::MatrixXd T = Eigen::MatrixXd::Zero(m, m);
            for (int i = 0; i < m; ++i) T(i, i) = alpha[i];
            for (int i = 0; i + 1 < m; ++i) T(i, i + 1) = T(i + 1, i) = beta[i];
            Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(T);
            const double scale = eig.eigenvalues().cwiseAbs().maxCoeff();
            ritz = eig.eigenvectors().col(0);
            result.lambda_min = eig.eigenvalues()(0);
            const double estimate = std::abs(b * ritz(m - 1));
            const bool converged = estimate <= config.tolerance * scale || b < kBreakdown;
            if (converged) result.status = DistributedEigenResult::Status::kConverged;
            done = breakdown || converged;
        }
        beta.push_back(b);
        if (!done) {
            for (auto& s : w) s /= b;
            q = std::move(w);
        }
    }
    Segments v(robots.size());
    for (size_t k = 0; k < robots.size(); ++k) v[k] = Eigen::VectorXd::Zero(robots[k].own.rows());
    for (Eigen::Index i = 0; i < ritz.size(); ++i) Axpy(ritz(i), basis[i], &v);
    const double vn = std::sqrt(Dot(v, v));
    for (auto& s : v) s /= vn;
    Segments Sv = team.Multiply(v, &result);
    result.lambda_min = Dot(v, Sv);
    Axpy(-result.lambda_min, v, &Sv);
    result.residual = std::sqrt(Dot(Sv, Sv));
    result.scalar_reductions += 3;
    result.vector = std::move(v);
    return result;
}

}  // namespace certislam::certify
