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

/// Setup sums, in message order.
enum SetupIndex { kCost, kGradientSq, kQRowSum, kTraceLambda, kStartNormSq, kDimension, kSetupN };

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
}

LanczosParticipant::LanczosParticipant(LocalCertificateProblem problem, std::vector<int> team,
                                       std::uint64_t round, const LanczosSettings& settings,
                                       VectorSender send_vector, ReductionSender send_reduction)
    : problem_(std::move(problem)),
      team_(std::move(team)),
      settings_(settings),
      send_vector_(std::move(send_vector)),
      send_reduction_(std::move(send_reduction)) {
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
    std::vector<double> setup(kSetupN);
    setup[kCost] = problem_.cost;
    setup[kGradientSq] = problem_.gradient_sq;
    setup[kQRowSum] = problem_.q_row_sum;
    setup[kTraceLambda] = rows.trace_lambda;
    setup[kStartNormSq] = q.squaredNorm();
    setup[kDimension] = static_cast<double>(q.size());
    Share(0, kSetupStage, setup);
    SendVector(0, q);  // unnormalised: every reader divides by the norm from the setup sums
    Advance();
}

void LanczosParticipant::OnVector(int robot, int step, const std::vector<slam::PoseId>& ids,
                                  const Eigen::VectorXd& values) {
    if (done_ || step < step_ || !problem_.neighbor_robots.count(robot)) return;
    vectors_[step][robot] = {ids, values};
    Advance();
}

void LanczosParticipant::OnReduction(int robot, int step, int stage,
                                     const std::vector<double>& values) {
    if (done_ || step < step_ || robot == problem_.robot) return;
    partials_[{step, stage}][robot] = values;
    Advance();
}

bool LanczosParticipant::Reduced(int step, int stage, std::vector<double>* sums,
                                 bool max_of_third) {
    const auto it = partials_.find({step, stage});
    if (it == partials_.end() || it->second.size() < team_.size()) return false;
    sums->clear();
    for (const int r : team_) {  // the same order on every robot: the same sums, bit for bit
        const auto p = it->second.find(r);
        if (p == it->second.end()) return false;
        if (sums->empty()) sums->assign(p->second.size(), 0.0);
        if (p->second.size() != sums->size()) return false;
        for (size_t i = 0; i < sums->size(); ++i) {
            (*sums)[i] = max_of_third && i == kQRowSum ? std::max((*sums)[i], p->second[i])
                                                       : (*sums)[i] + p->second[i];
        }
    }
    partials_.erase(it);
    return true;
}

void LanczosParticipant::Share(int step, int stage, const std::vector<double>& values) {
    partials_[{step, stage}][problem_.robot] = values;
    send_reduction_(step, stage, values);
}

void LanczosParticipant::SendVector(int step, const Eigen::VectorXd& u) {
    if (problem_.public_ids.empty()) return;
    const Eigen::VectorXd entries = PublicEntries(problem_.rows, u);
    verdict_.entries_sent += static_cast<double>(entries.size());
    send_vector_(step, problem_.public_ids, entries);
}

bool LanczosParticipant::Product() {
    const auto it = vectors_.find(step_);
    for (const int r : problem_.neighbor_robots) {
        if (it == vectors_.end() || !it->second.count(r)) return false;
    }
    // Finish every neighbour's vector of this step: (u - V c) / beta, as its owner did.
    for (const int r : problem_.neighbor_robots) {
        Eigen::VectorXd& values = it->second.at(r).second;
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
    const int b = problem_.rows.d + 1;
    Eigen::VectorXd nbr(b * static_cast<Eigen::Index>(problem_.neighbor_ids.size()));
    for (size_t k = 0; k < problem_.neighbor_ids.size(); ++k) {
        const slam::PoseId& id = problem_.neighbor_ids[k];
        const auto& [ids, values] = it->second.at(id.robot);
        const auto pos = std::find(ids.begin(), ids.end(), id);
        if (pos == ids.end() || values.size() != b * static_cast<Eigen::Index>(ids.size())) {
            Finish(DistributedVerdict::Status::kInconsistent);
            return false;
        }
        nbr.segment(b * k, b) = values.segment(b * (pos - ids.begin()), b);
    }
    if (it != vectors_.end()) vectors_.erase(it);
    w_ = MultiplyRows(problem_.rows, basis_.back(), nbr);
    return true;
}

void LanczosParticipant::Advance() {
    std::vector<double> sums;
    while (!done_) {
        switch (phase_) {
            case Phase::kSetup: {
                if (!Reduced(0, kSetupStage, &sums, true)) return;
                verdict_.cost = sums[kCost];
                verdict_.gradient_norm = std::sqrt(sums[kGradientSq]);
                verdict_.q_norm = sums[kQRowSum];
                verdict_.dual_value = sums[kTraceLambda];
                verdict_.eta = settings_.eta_relative * verdict_.q_norm;
                verdict_.gradient_tolerance = settings_.gradient_tolerance_relative * 2.0 *
                                              std::sqrt(verdict_.q_norm * std::abs(verdict_.cost));
                // Not a critical point: no eigenvalue can make a verdict (the centralised check
                // stops here too), so no Lanczos step is spent.
                if (verdict_.gradient_norm > verdict_.gradient_tolerance) {
                    return Finish(DistributedVerdict::Status::kNotCritical);
                }
                max_steps_ = std::min(settings_.max_krylov, static_cast<int>(sums[kDimension]));
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
                if (!Reduced(step_, kPass1Stage, &sums)) return;
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
                if (!Reduced(step_, kPass2Stage, &sums)) return;
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
                    return Finish(converged ? DistributedVerdict::Status::kCertified
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
    // kCertified here only means "converged": the verdict follows the centralised rules.
    if (status == DistributedVerdict::Status::kCertified) {
        if (verdict_.gradient_norm > verdict_.gradient_tolerance) {
            status = DistributedVerdict::Status::kNotCritical;
        } else if (verdict_.lambda_min < -verdict_.eta) {
            status = DistributedVerdict::Status::kNotCertified;
        }
    }
    verdict_.status = status;
    done_ = true;
    vectors_.clear();
    partials_.clear();
}

namespace {

using Segments = std::vector<Eigen::VectorXd>;

double Dot(const Segments& a, const Segments& b) {
    double s = 0.0;
    for (size_t k = 0; k < a.size(); ++k) s += a[k].dot(b[k]);
    return s;
}

/// Robot k's problem from its rows alone: poses named (owner, global index); no X, so no cost
/// and no gradient (both zero: the gradient test passes trivially).
std::vector<LocalCertificateProblem> ProblemsOf(const std::vector<CertificateRows>& robots) {
    std::map<int, int> owner;  // public global pose -> robot
    for (size_t k = 0; k < robots.size(); ++k) {
        for (const int g : robots[k].public_poses) owner[g] = static_cast<int>(k);
    }
    std::vector<LocalCertificateProblem> problems(robots.size());
    for (size_t k = 0; k < robots.size(); ++k) {
        LocalCertificateProblem& p = problems[k];
        p.robot = static_cast<int>(k);
        p.rows = robots[k];
        for (const int g : p.rows.public_poses) p.public_ids.push_back({p.robot, g});
        for (const int g : p.rows.neighbor_poses) {
            const auto it = owner.find(g);
            CERTISLAM_CHECK(it != owner.end());  // every neighbour pose is public at its owner
            p.neighbor_ids.push_back({it->second, g});
            p.neighbor_robots.insert(it->second);
        }
    }
    return problems;
}

/// The exact product S v over the team (for the residual of the final Ritz vector).
Segments Multiply(const std::vector<LocalCertificateProblem>& problems, const Segments& v) {
    std::map<slam::PoseId, Eigen::VectorXd> published;
    for (size_t k = 0; k < problems.size(); ++k) {
        const int b = problems[k].rows.d + 1;
        const Eigen::VectorXd entries = PublicEntries(problems[k].rows, v[k]);
        for (size_t p = 0; p < problems[k].public_ids.size(); ++p) {
            published[problems[k].public_ids[p]] = entries.segment(b * p, b);
        }
    }
    Segments out(problems.size());
    for (size_t k = 0; k < problems.size(); ++k) {
        const int b = problems[k].rows.d + 1;
        Eigen::VectorXd nbr(b * static_cast<Eigen::Index>(problems[k].neighbor_ids.size()));
        for (size_t p = 0; p < problems[k].neighbor_ids.size(); ++p) {
            nbr.segment(b * p, b) = published.at(problems[k].neighbor_ids[p]);
        }
        out[k] = MultiplyRows(problems[k].rows, v[k], nbr);
    }
    return out;
}

}  // namespace

DistributedEigenResult DistributedMinEigenpair(const std::vector<CertificateRows>& robots,
                                               const LanczosSettings& settings) {
    settings.Validate();
    CERTISLAM_CHECK(!robots.empty());
    const std::vector<LocalCertificateProblem> problems = ProblemsOf(robots);
    std::vector<int> team(robots.size());
    for (size_t k = 0; k < team.size(); ++k) team[k] = static_cast<int>(k);
    DistributedEigenResult result;
    std::deque<std::function<void()>> mail;  // deliveries in send order
    std::vector<std::unique_ptr<LanczosParticipant>> robot(robots.size());
    std::set<std::pair<int, int>> exchanges, reductions;  // (step, stage) seen
    for (size_t k = 0; k < robots.size(); ++k) {
        const int from = static_cast<int>(k);
        auto send_vector = [&, from](int step, const std::vector<slam::PoseId>& ids,
                                     const Eigen::VectorXd& values) {
            exchanges.insert({step, 0});
            result.entries_exchanged += static_cast<double>(values.size());
            for (size_t to = 0; to < problems.size(); ++to) {
                if (!problems[to].neighbor_robots.count(from)) continue;
                mail.push_back([&, to, from, step, ids, values] {
                    robot[to]->OnVector(from, step, ids, values);
                });
            }
        };
        auto send_reduction = [&, from](int step, int stage, const std::vector<double>& values) {
            reductions.insert({step, stage});
            for (size_t to = 0; to < problems.size(); ++to) {
                if (static_cast<int>(to) == from) continue;
                mail.push_back([&, to, from, step, stage, values] {
                    robot[to]->OnReduction(from, step, stage, values);
                });
            }
        };
        robot[k] = std::make_unique<LanczosParticipant>(problems[k], team, 0, settings, send_vector,
                                                        send_reduction);
    }
    for (auto& r : robot) r->Begin();
    while (!mail.empty()) {
        const auto deliver = std::move(mail.front());
        mail.pop_front();
        deliver();
    }
    const DistributedVerdict& verdict = robot.front()->Verdict();
    CERTISLAM_CHECK(verdict.status != DistributedVerdict::Status::kInconsistent);
    result.status = verdict.status == DistributedVerdict::Status::kNotConverged
                        ? DistributedEigenResult::Status::kNotConverged
                        : DistributedEigenResult::Status::kConverged;
    result.steps = verdict.steps;
    Segments v(robots.size());
    for (size_t k = 0; k < robots.size(); ++k) v[k] = robot[k]->RitzSegment();
    const double norm = std::sqrt(Dot(v, v));
    for (auto& s : v) s /= norm;
    Segments Sv = Multiply(problems, v);
    for (const auto& p : problems) {
        result.entries_exchanged += (p.rows.d + 1.0) * static_cast<double>(p.public_ids.size());
    }
    result.lambda_min = Dot(v, Sv);
    for (size_t k = 0; k < v.size(); ++k) Sv[k] -= result.lambda_min * v[k];
    result.residual = std::sqrt(Dot(Sv, Sv));
    result.products = result.steps + 1;
    result.vector_exchanges = static_cast<int>(exchanges.size()) + 1;
    result.scalar_reductions = static_cast<int>(reductions.size()) + 3;  // ||v||, v^T S v, ||r||
    result.vector = std::move(v);
    return result;
}

}  // namespace certislam::certify
