// One robot's message-driven share of the distributed Lanczos, and a team of them whose
// messages are delivered in memory.
#include "certify/distributed/distributed_lanczos.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <deque>
#include <limits>
#include <memory>
#include <random>
#include <set>
#include <stdexcept>
#include <string>

#include "slam/core/check.h"

namespace certislam::certify {
namespace {

constexpr double kBreakdown = 1e-300;       ///< beta below this: the Krylov space is invariant
constexpr int kSetupStage = 0;              ///< reduction of the setup sums (step 0)
constexpr int kPass1Stage = 1;              ///< alpha = v_k^T S v_k
constexpr int kPass2Stage = 2;              ///< full reorthogonalisation pass and the squared norm
constexpr int kBisections = 200;            ///< bisection steps at most (each halves the bracket)
constexpr std::uint64_t kRobotSeed = 7919;  ///< start vector seed stride per robot

constexpr double kInverseIterationShift = 1e-10;  ///< shift below lambda, relative to max |Ritz|
constexpr int kInverseIterationSweeps = 3;        ///< sweeps of inverse iteration

/// Lanczos's own setup sum, after the shared ones (SetupShares).
constexpr int kStartNormSq = kSetupShared;

/// u -= sum_i c_i V_i, element by element in i order: the owner of a Lanczos vector and every
/// reader of its public entries do the same operations, so they hold the same numbers.
void SubtractCombination(Eigen::VectorXd* u, const std::vector<Eigen::VectorXd>& V,
                         const std::vector<double>& c) {
    for (size_t i = 0; i < V.size(); ++i) *u -= c[i] * V[i];
}

/// Eigenvalues of the tridiagonal T (diagonal a, off-diagonal off) below x (Sturm count).
int CountBelow(const Eigen::VectorXd& a, const Eigen::VectorXd& off, double x) {
    int count = 0;
    double d = 1.0;
    for (Eigen::Index i = 0; i < a.size(); ++i) {
        d = a(i) - x - (i > 0 ? off(i - 1) * off(i - 1) / d : 0.0);
        if (d == 0.0) d = -std::numeric_limits<double>::min();  // x is an eigenvalue: below
        if (d < 0.0) ++count;
    }
    return count;
}

/// The k-th smallest eigenvalue (k from 0) of the tridiagonal T by bisection on the Sturm count:
/// O(m) per halving instead of the O(m^2) of a full tridiagonal eigen-decomposition, so the
/// Ritz values can be checked every few steps of a long Lanczos run.
double TridiagonalEigenvalue(const Eigen::VectorXd& a, const Eigen::VectorXd& off, int k) {
    double lo = a(0), hi = a(0);
    for (Eigen::Index i = 0; i < a.size(); ++i) {  // Gershgorin
        const double radius =
            (i > 0 ? std::abs(off(i - 1)) : 0.0) + (i + 1 < a.size() ? std::abs(off(i)) : 0.0);
        lo = std::min(lo, a(i) - radius);
        hi = std::max(hi, a(i) + radius);
    }
    const double width = std::max(std::abs(lo), std::abs(hi));
    for (int it = 0; it < kBisections; ++it) {
        const double mid = 0.5 * (lo + hi);
        if (hi - lo <= 2.0 * std::numeric_limits<double>::epsilon() * width || mid <= lo ||
            mid >= hi) {
            break;
        }
        (CountBelow(a, off, mid) > k ? hi : lo) = mid;
    }
    return 0.5 * (lo + hi);
}

/// Unit eigenvector of the tridiagonal T (diagonal a, off-diagonal off) for its smallest
/// eigenvalue `lambda`: inverse iteration with T - (lambda - delta) I, which is positive definite,
/// so the Thomas algorithm is stable (O(m) per sweep).
Eigen::VectorXd TridiagonalEigenvector(const Eigen::VectorXd& a, const Eigen::VectorXd& off,
                                       double lambda, double scale) {
    const Eigen::Index m = a.size();
    const double sigma = lambda - kInverseIterationShift * std::max(scale, 1e-300);
    Eigen::VectorXd y = Eigen::VectorXd::Ones(m);
    Eigen::VectorXd c(m), d(m);
    for (int sweep = 0; sweep < kInverseIterationSweeps; ++sweep) {
        double pivot = a(0) - sigma;
        c(0) = m > 1 ? off(0) / pivot : 0.0;
        d(0) = y(0) / pivot;
        for (Eigen::Index i = 1; i < m; ++i) {
            pivot = a(i) - sigma - off(i - 1) * c(i - 1);
            c(i) = i + 1 < m ? off(i) / pivot : 0.0;
            d(i) = (y(i) - off(i - 1) * d(i - 1)) / pivot;
        }
        y(m - 1) = d(m - 1);
        for (Eigen::Index i = m - 2; i >= 0; --i) y(i) = d(i) - c(i) * y(i + 1);
        y.normalize();
    }
    return y;
}

}  // namespace

CertificateQuantities QuantitiesOf(const DistributedVerdict& v) {
    CertificateQuantities q;
    q.d = 3;
    q.n = v.poses;
    q.objective = v.cost;
    q.dual_value = v.dual_value;
    q.q_norm = v.q_norm;
    q.gradient_norm = v.gradient_norm;
    q.x_norm = v.x_norm;
    q.objective_noise = v.objective_noise;
    return q;
}

void LanczosSettings::Validate() const {
    const auto fail = [](const std::string& field, double value, const std::string& rule) {
        throw std::invalid_argument("LanczosSettings." + field + " = " + std::to_string(value) +
                                    ": must be " + rule);
    };
    if (max_krylov < 2) fail("max_krylov", max_krylov, ">= 2");
    if (!(tolerance > 0.0)) fail("tolerance", tolerance, "> 0");
    if (check_every < 1) fail("check_every", check_every, ">= 1");
    if (!(eta_relative >= 0.0)) fail("eta_relative", eta_relative, ">= 0");
    if (!(gradient_tolerance_relative >= 0.0)) {
        fail("gradient_tolerance_relative", gradient_tolerance_relative, ">= 0");
    }
    lobpcg.Validate();
}

LanczosParticipant::LanczosParticipant(LocalCertificateProblem problem, std::vector<int> team,
                                       std::uint64_t round, const LanczosSettings& settings,
                                       VectorSender send_vector, ReductionSender send_reduction)
    : problem_(std::move(problem)),
      team_(std::move(team)),
      settings_(settings),
      send_vector_(std::move(send_vector)),
      send_reduction_(std::move(send_reduction)),
      mailbox_(problem_.robot, team_, problem_.neighbor_robots) {
    settings_.Validate();
    verdict_.round = round;
}

void LanczosParticipant::Begin() {
    const CertificateRows& rows = problem_.rows;
    std::mt19937_64 rng(settings_.seed + kRobotSeed * static_cast<std::uint64_t>(problem_.robot));
    std::normal_distribution<double> normal;
    Eigen::VectorXd q(rows.own.rows());
    for (Eigen::Index i = 0; i < q.size(); ++i) q[i] = normal(rng);
    basis_.push_back(q);
    Share(0, kSetupStage, SetupShares(problem_, {q.squaredNorm()}));
    SendVector(0, q);  // unnormalised: every reader divides by the norm from the setup sums
    Advance();
}

void LanczosParticipant::OnVector(int robot, int step, const std::vector<slam::PoseId>& ids,
                                  const Eigen::VectorXd& values) {
    if (done_) return;
    mailbox_.PutVector(robot, step, step_, ids, values);
    Advance();
}

void LanczosParticipant::OnReduction(int robot, int step, int stage,
                                     const std::vector<double>& values) {
    if (done_) return;
    mailbox_.PutPartial(robot, step, stage, step_, values);
    Advance();
}

void LanczosParticipant::Share(int step, int stage, const std::vector<double>& values) {
    mailbox_.PutOwn(step, stage, values);
    send_reduction_(step, stage, values);
}

void LanczosParticipant::SendVector(int step, const Eigen::VectorXd& u) {
    if (problem_.public_ids.empty()) return;
    const Eigen::VectorXd entries = PublicEntries(problem_.rows, u);
    verdict_.entries_sent += static_cast<double>(entries.size());
    send_vector_(step, problem_.public_ids, entries);
}

bool LanczosParticipant::Product() {
    std::map<int, NeighborEntries>* vectors = mailbox_.Vectors(step_);
    if (vectors == nullptr) return false;
    // Finish every neighbour's vector of this step: (u - V c) / beta, as its owner did.
    for (const int r : problem_.neighbor_robots) {
        Eigen::VectorXd& values = vectors->at(r).second;
        auto& V = neighbor_basis_[r];
        bool consistent = V.size() == pending_c_.size();
        for (const auto& old : V) consistent = consistent && old.size() == values.size();
        if (!consistent) {
            Finish(DistributedVerdict::Status::kInconsistent);
            return false;
        }
        SubtractCombination(&values, V, pending_c_);
        values /= pending_b_;
        V.push_back(values);
    }
    Eigen::MatrixXd nbr;
    if (!GatherNeighborEntries(problem_, *vectors, 1, &nbr)) {
        Finish(DistributedVerdict::Status::kInconsistent);
        return false;
    }
    mailbox_.EraseVectors(step_);
    w_ = MultiplyRows(problem_.rows, basis_.back(), nbr.col(0));
    return true;
}

void LanczosParticipant::Advance() {
    std::vector<double> sums;
    while (!done_) {
        switch (phase_) {
            case Phase::kSetup: {
                if (!mailbox_.Reduce(0, kSetupStage, &sums, {kSetupQRowSum})) return;
                if (sums.size() != kStartNormSq + 1) {
                    return Finish(DistributedVerdict::Status::kInconsistent);
                }
                // Not a critical point: no Lanczos step is spent (the centralised check stops
                // here too, by the same rule).
                if (!ReadSetupSums(sums, problem_.rows.d, settings_, &verdict_)) {
                    return Finish(DistributedVerdict::Status::kNotCritical);
                }
                max_steps_ =
                    std::min(settings_.max_krylov, static_cast<int>(sums[kSetupDimension]));
                pending_c_.clear();
                pending_b_ = std::sqrt(sums[kStartNormSq]);
                basis_.back() /= pending_b_;
                phase_ = Phase::kProduct;
                break;
            }
            case Phase::kProduct: {
                if (!Product()) return;
                Share(step_, kPass1Stage, {basis_.back().dot(w_)});
                phase_ = Phase::kPass1;
                break;
            }
            case Phase::kPass1: {
                if (!mailbox_.Reduce(step_, kPass1Stage, &sums)) return;
                if (sums.size() != 1) return Finish(DistributedVerdict::Status::kInconsistent);
                // Three-term recurrence, then one full Gram-Schmidt pass against every vector
                // (the recurrence removed the large components; the pass removes the rest).
                alpha_.push_back(sums[0]);
                w_ -= sums[0] * basis_.back();
                if (!beta_.empty()) w_ -= beta_.back() * basis_[basis_.size() - 2];
                std::vector<double> next;
                for (const auto& u : basis_) next.push_back(u.dot(w_));
                next.push_back(w_.squaredNorm());
                Share(step_, kPass2Stage, next);
                // The next vector's public entries before its second pass: readers finish it.
                if (static_cast<int>(alpha_.size()) < max_steps_) SendVector(step_ + 1, w_);
                phase_ = Phase::kPass2;
                break;
            }
            case Phase::kPass2: {
                if (!mailbox_.Reduce(step_, kPass2Stage, &sums)) return;
                if (sums.size() != basis_.size() + 1)
                    return Finish(DistributedVerdict::Status::kInconsistent);
                const double norm_sq = sums.back();
                sums.pop_back();
                SubtractCombination(&w_, basis_, sums);
                // ||w - V c||^2 = ||w||^2 - ||c||^2 for orthonormal V (c is tiny after pass 1).
                double c_sq = 0.0;
                for (const double c : sums) c_sq += c * c;
                const double b = std::sqrt(std::max(norm_sq - c_sq, 0.0));
                const int m = static_cast<int>(alpha_.size());
                const bool last = b < kBreakdown || m >= max_steps_;
                const bool converged = (last || m % settings_.check_every == 0) && Converged(b);
                if (converged || last) {
                    return Finish(converged ? DistributedVerdict::Status::kConverged
                                            : DistributedVerdict::Status::kNotConverged);
                }
                beta_.push_back(b);
                basis_.emplace_back(w_ / b);
                pending_c_ = std::move(sums);
                pending_b_ = b;
                ++step_;
                phase_ = Phase::kProduct;
                break;
            }
        }
    }
}

bool LanczosParticipant::Converged(double b) {
    const int m = static_cast<int>(alpha_.size());
    const Eigen::VectorXd a = Eigen::Map<const Eigen::VectorXd>(alpha_.data(), m);
    const Eigen::VectorXd off = Eigen::Map<const Eigen::VectorXd>(beta_.data(), m - 1);
    verdict_.lambda_min = TridiagonalEigenvalue(a, off, 0);
    const double scale =
        std::max(std::abs(verdict_.lambda_min), std::abs(TridiagonalEigenvalue(a, off, m - 1)));
    ritz_ = TridiagonalEigenvector(a, off, verdict_.lambda_min, scale);
    verdict_.residual_estimate = std::abs(b * ritz_(m - 1));
    verdict_.steps = m;
    return verdict_.residual_estimate <= settings_.tolerance * scale || b < kBreakdown;
}

Eigen::VectorXd LanczosParticipant::RitzSegment() const {
    Eigen::VectorXd v = Eigen::VectorXd::Zero(problem_.rows.own.rows());
    for (Eigen::Index i = 0; i < ritz_.size(); ++i) v += ritz_(i) * basis_[i];
    return v;
}

void LanczosParticipant::Finish(DistributedVerdict::Status status) {
    verdict_.status = status;
    done_ = true;
    mailbox_.Clear();
}

}  // namespace certislam::certify
