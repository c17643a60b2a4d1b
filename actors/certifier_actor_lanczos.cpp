// A robot's rows of S and its message-driven share of certify's distributed Lanczos (the same
// iteration as certify::DistributedMinEigenpair, cut at every exchange so messages can drive it).
#include "actors/certifier_actor_lanczos.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <random>

#include "slam/connection_laplacian.h"
#include "slam/partition.h"
#include "slam/pose_graph.h"

namespace certislam::actors {
namespace {

constexpr int kBlock = 4;                   ///< columns per pose, d + 1 with d = 3
constexpr double kBreakdown = 1e-300;       ///< beta below this: the Krylov space is invariant
constexpr int kSetupStage = 0;              ///< reduction of the setup sums (step 0)
constexpr int kPass1Stage = 1;              ///< first reorthogonalisation pass
constexpr int kPass2Stage = 2;              ///< second pass ("twice is enough")
constexpr int kNormStage = 3;               ///< squared norm of the new direction
constexpr std::uint64_t kRobotSeed = 7919;  ///< start vector seed stride per robot
constexpr double kInverseIterationShift = 1e-10;  ///< shift below lambda, relative to max |Ritz|
constexpr int kInverseIterationSweeps = 3;        ///< sweeps of inverse iteration

/// Setup sums, in message order.
enum SetupIndex { kCost, kGradientSq, kQRowSum, kTraceLambda, kStartNormSq, kDimension, kSetupN };

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

bool MakeLocalProblem(int robot, const std::vector<slam::PoseId>& own_ids,
                      const Eigen::MatrixXd& X_own, const std::vector<slam::LoopClosure>& edges,
                      const std::map<slam::PoseId, Eigen::MatrixXd>& neighbor_blocks,
                      LocalCertificateProblem* out) {
    const int n = static_cast<int>(own_ids.size());
    std::map<slam::PoseId, int> local;
    for (int i = 0; i < n; ++i) local[own_ids[static_cast<size_t>(i)]] = i;
    slam::PoseGraph graph;
    graph.d = 3;
    graph.ids = own_ids;
    for (const auto& e : edges) {
        for (const slam::PoseId& id : {e.a, e.b}) {
            if (local.count(id)) continue;
            if (!neighbor_blocks.count(id)) return false;
            local[id] = static_cast<int>(graph.ids.size());
            graph.ids.push_back(id);
        }
        slam::RelativePoseMeasurement m;
        m.i = local.at(e.a);
        m.j = local.at(e.b);
        m.R = e.T_a_b.linear();
        m.t = e.T_a_b.translation();
        m.kappa = e.kappa;
        m.tau = e.tau;
        graph.edges.push_back(m);
    }
    graph.n = static_cast<int>(graph.ids.size());
    Eigen::MatrixXd X(X_own.rows(), kBlock * graph.n);
    X.leftCols(X_own.cols()) = X_own;
    for (int g = n; g < graph.n; ++g) {
        X.middleCols(kBlock * g, kBlock) = neighbor_blocks.at(graph.ids[static_cast<size_t>(g)]);
    }
    // Only Q's own columns are read below: they hold exactly the edges at own poses.
    const Eigen::SparseMatrix<double> Q = slam::ConnectionLaplacian(graph);
    slam::Partition partition;
    partition.begin = {0, n, graph.n};
    LocalCertificateProblem p;
    p.robot = robot;
    p.rows = certify::MakeCertificateRows(Q, X, 3, partition, 0);
    for (int g : p.rows.public_poses) p.public_ids.push_back(graph.ids[static_cast<size_t>(g)]);
    Eigen::MatrixXd X_nbr(X.rows(), kBlock * p.rows.neighbor_poses.size());
    for (size_t k = 0; k < p.rows.neighbor_poses.size(); ++k) {
        const slam::PoseId id = graph.ids[static_cast<size_t>(p.rows.neighbor_poses[k])];
        p.neighbor_ids.push_back(id);
        p.neighbor_robots.insert(id.robot);
        X_nbr.middleCols(kBlock * k, kBlock) =
            X.middleCols(kBlock * p.rows.neighbor_poses[k], kBlock);
    }
    const Eigen::SparseMatrix<double> Q_own = Q.leftCols(kBlock * n);
    const Eigen::MatrixXd XQ_own = X * Q_own;  // (X Q)[:, own columns]
    p.cost = XQ_own.cwiseProduct(X_own).sum();
    Eigen::MatrixXd G = p.rows.own * X_own.transpose();  // (S X^T)[own rows, :]
    if (p.rows.nbr.cols() > 0) G += p.rows.nbr * X_nbr.transpose();
    p.gradient_sq = 4.0 * G.squaredNorm();  // grad f = 2 X S (Riemannian at a critical point)
    for (int c = 0; c < kBlock * n; ++c) {
        double sum = 0.0;
        for (Eigen::SparseMatrix<double>::InnerIterator it(Q, c); it; ++it)
            sum += std::abs(it.value());
        p.q_row_sum = std::max(p.q_row_sum, sum);
    }
    *out = std::move(p);
    return true;
}

LanczosParticipant::LanczosParticipant(LocalCertificateProblem problem, std::vector<int> team,
                                       std::uint64_t round, const LanczosSettings& settings,
                                       VectorSender send_vector, ReductionSender send_reduction)
    : problem_(std::move(problem)),
      team_(std::move(team)),
      settings_(settings),
      send_vector_(std::move(send_vector)),
      send_reduction_(std::move(send_reduction)) {
    verdict_.round = round;
}

void LanczosParticipant::Begin() {
    const certify::CertificateRows& rows = problem_.rows;
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

void LanczosParticipant::SendVector() {
    const Eigen::VectorXd entries = certify::PublicEntries(problem_.rows, basis_.back());
    if (problem_.public_ids.empty()) return;
    verdict_.entries_sent += static_cast<double>(entries.size());
    send_vector_(step_, problem_.public_ids, entries);
}

bool LanczosParticipant::Product() {
    const auto it = vectors_.find(step_);
    for (const int r : problem_.neighbor_robots) {
        if (it == vectors_.end() || !it->second.count(r)) return false;
    }
    Eigen::VectorXd nbr(kBlock * problem_.neighbor_ids.size());
    for (size_t k = 0; k < problem_.neighbor_ids.size(); ++k) {
        const slam::PoseId& id = problem_.neighbor_ids[k];
        const auto& [ids, values] = it->second.at(id.robot);
        const auto pos = std::find(ids.begin(), ids.end(), id);
        if (pos == ids.end() || values.size() != kBlock * static_cast<Eigen::Index>(ids.size())) {
            Finish(DistributedVerdict::Status::kInconsistent);
            return false;
        }
        nbr.segment(kBlock * k, kBlock) = values.segment(kBlock * (pos - ids.begin()), kBlock);
    }
    if (it != vectors_.end()) vectors_.erase(it);
    w_ = certify::MultiplyRows(problem_.rows, basis_.back(), nbr);
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
                max_steps_ = std::min(settings_.max_krylov, static_cast<int>(sums[kDimension]));
                basis_.back() /= std::sqrt(sums[kStartNormSq]);
                SendVector();
                phase_ = Phase::kProduct;
                break;
            }
            case Phase::kProduct: {
                if (!Product()) return;
                std::vector<double> c;
                for (const auto& u : basis_) c.push_back(u.dot(w_));
                Share(step_, kPass1Stage, c);
                phase_ = Phase::kPass1;
                break;
            }
            case Phase::kPass1:
            case Phase::kPass2: {
                const bool first = phase_ == Phase::kPass1;
                if (!Reduced(step_, first ? kPass1Stage : kPass2Stage, &sums)) return;
                if (sums.size() != basis_.size())
                    return Finish(DistributedVerdict::Status::kInconsistent);
                if (first) alpha_.push_back(sums[static_cast<size_t>(step_)]);
                for (size_t i = 0; i < basis_.size(); ++i) w_ -= sums[i] * basis_[i];
                std::vector<double> next;
                if (first) {
                    for (const auto& u : basis_) next.push_back(u.dot(w_));
                } else {
                    next.push_back(w_.squaredNorm());
                }
                Share(step_, first ? kPass2Stage : kNormStage, next);
                phase_ = first ? Phase::kPass2 : Phase::kNorm;
                break;
            }
            case Phase::kNorm: {
                if (!Reduced(step_, kNormStage, &sums)) return;
                const double b = std::sqrt(sums[0]);
                const int m = static_cast<int>(alpha_.size());
                const bool last = b < kBreakdown || m >= max_steps_;
                // Checks get rarer as the basis grows (each costs O(m^2)).
                const int every = std::max(settings_.check_every, m / 20);
                const bool converged = (last || m % every == 0) && Converged(b);
                if (converged || last) {
                    return Finish(converged ? DistributedVerdict::Status::kCertified
                                            : DistributedVerdict::Status::kNotConverged);
                }
                beta_.push_back(b);
                basis_.emplace_back(w_ / b);
                ++step_;
                SendVector();
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
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig;
    eig.computeFromTridiagonal(a, off, Eigen::EigenvaluesOnly);  // O(m^2): no dense T
    const double scale = eig.eigenvalues().cwiseAbs().maxCoeff();
    verdict_.lambda_min = eig.eigenvalues()(0);
    const Eigen::VectorXd y = TridiagonalEigenvector(a, off, verdict_.lambda_min, scale);
    verdict_.residual_estimate = std::abs(b * y(m - 1));
    verdict_.steps = m;
    return verdict_.residual_estimate <= settings_.tolerance * scale || b < kBreakdown;
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

}  // namespace certislam::actors
