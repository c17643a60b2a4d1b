// One robot's message-driven share of the distributed LOBPCG, and the choice of participant.
#include "certify/distributed/lobpcg_participant.h"

#include <Eigen/CholmodSupport>
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <random>

#include "certify/certificate.h"
#include "slam/core/check.h"

namespace certislam::certify {
namespace {

/// Iterations without the recurrence residual halving before S X is recomputed exactly.
constexpr int kStallIterations = 10;

constexpr int kSetupStage = 0;              ///< reduction of the setup sums (step 0)
constexpr int kSumsStage = 1;               ///< the reduction of exchange e (step e)
constexpr std::uint64_t kRobotSeed = 7919;  ///< start block seed stride per robot
constexpr int kMaxShiftAttempts = 40;       ///< factorisations tried at most

/// LOBPCG's own setup sum, after the shared ones (SetupShares): ||S||_inf, a maximum.
constexpr int kSRowSum = kSetupShared;

/// Largest absolute row sum of the robot's rows of S.
double RowSumOfS(const CertificateRows& rows) {
    Eigen::VectorXd sums = Eigen::VectorXd::Zero(rows.own.rows());
    for (const auto* M : {&rows.own, &rows.nbr}) {
        for (Eigen::Index c = 0; c < M->outerSize(); ++c) {
            for (Eigen::SparseMatrix<double>::InnerIterator it(*M, c); it; ++it) {
                sums(it.row()) += std::abs(it.value());
            }
        }
    }
    return sums.size() > 0 ? sums.maxCoeff() : 0.0;
}

}  // namespace

struct LobpcgParticipant::Factor {
    Eigen::CholmodDecomposition<Eigen::SparseMatrix<double>, Eigen::Lower> llt;
};

std::unique_ptr<RoundParticipant> MakeRoundParticipant(
    LocalCertificateProblem problem, std::vector<int> team, std::uint64_t round,
    const LanczosSettings& settings, RoundParticipant::VectorSender send_vector,
    RoundParticipant::ReductionSender send_reduction) {
    if (settings.method == LanczosSettings::Method::kLobpcg) {
        return std::make_unique<LobpcgParticipant>(std::move(problem), std::move(team), round,
                                                   settings, std::move(send_vector),
                                                   std::move(send_reduction));
    }
    return std::make_unique<LanczosParticipant>(std::move(problem), std::move(team), round,
                                                settings, std::move(send_vector),
                                                std::move(send_reduction));
}

LobpcgParticipant::LobpcgParticipant(LocalCertificateProblem problem, std::vector<int> team,
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

LobpcgParticipant::~LobpcgParticipant() = default;

void LobpcgParticipant::Begin() {
    const CertificateRows& rows = problem_.rows;
    const LobpcgSettings& s = settings_.lobpcg;
    std::mt19937_64 rng(s.seed + kRobotSeed * static_cast<std::uint64_t>(problem_.robot));
    std::normal_distribution<double> normal;
    X_.resize(rows.own.rows(), s.block_size);
    P_.resize(rows.own.rows(), 0);
    AP_.resize(rows.own.rows(), 0);
    for (Eigen::Index i = 0; i < X_.size(); ++i) X_.data()[i] = normal(rng);
    Share(0, kSetupStage, SetupShares(problem_, {RowSumOfS(rows)}));
    SendBlock(X_, Purpose::kStart);  // exchange 0, before the setup sums are in (as Lanczos)
    Advance();
}

void LobpcgParticipant::OnVector(int robot, int step, const std::vector<slam::PoseId>& ids,
                                 const Eigen::VectorXd& values) {
    if (done_) return;
    mailbox_.PutVector(robot, step, exchange_, ids, values);
    Advance();
}

void LobpcgParticipant::OnReduction(int robot, int step, int stage,
                                    const std::vector<double>& values) {
    if (done_) return;
    mailbox_.PutPartial(robot, step, stage, exchange_, values);
    Advance();
}

Eigen::VectorXd LobpcgParticipant::RitzSegment() const {
    return ritz_.size() > 0 ? ritz_ : Eigen::VectorXd::Zero(problem_.rows.own.rows());
}

void LobpcgParticipant::Share(int step, int stage, const std::vector<double>& values) {
    ++progress_.reductions;
    progress_.scalars_reduced += static_cast<double>(values.size());
    mailbox_.PutOwn(step, stage, values);
    send_reduction_(step, stage, values);
}

void LobpcgParticipant::SendBlock(const Eigen::MatrixXd& B, Purpose purpose) {
    sent_ = B;
    purpose_ = purpose;
    ++progress_.exchanges;
    progress_.products += static_cast<int>(B.cols());
    if (problem_.public_ids.empty()) return;
    // One message per exchange: the block's columns one after another.
    const Eigen::Index per_column =
        (problem_.rows.d + 1) * static_cast<Eigen::Index>(problem_.public_ids.size());
    Eigen::VectorXd values(per_column * B.cols());
    for (Eigen::Index j = 0; j < B.cols(); ++j) {
        values.segment(j * per_column, per_column) = PublicEntries(problem_.rows, B.col(j));
    }
    verdict_.entries_sent += static_cast<double>(values.size());
    send_vector_(exchange_, problem_.public_ids, values);
}

bool LobpcgParticipant::Gather(Eigen::MatrixXd* neighbors) {
    const std::map<int, NeighborEntries>* vectors = mailbox_.Vectors(exchange_);
    if (vectors == nullptr) return false;
    if (!GatherNeighborEntries(problem_, *vectors, sent_.cols(), neighbors)) {
        Finish(DistributedVerdict::Status::kInconsistent);
        return false;
    }
    mailbox_.EraseVectors(exchange_);
    return true;
}

void LobpcgParticipant::Advance() {
    std::vector<double> sums;
    while (!done_) {
        switch (phase_) {
            case Phase::kSetup: {
                if (!mailbox_.Reduce(0, kSetupStage, &sums, {kSetupQRowSum, kSRowSum})) return;
                if (sums.size() != kSRowSum + 1) {
                    return Finish(DistributedVerdict::Status::kInconsistent);
                }
                if (!Setup(sums)) return;
                phase_ = Phase::kProduct;
                break;
            }
            case Phase::kProduct: {
                Eigen::MatrixXd neighbors;
                if (!Gather(&neighbors)) return;
                ++exchanges_done_;
                product_ = problem_.rows.own * sent_;
                if (problem_.rows.nbr.cols() > 0) product_ += problem_.rows.nbr * neighbors;
                Share(exchange_, kSumsStage, PartialSums());
                phase_ = Phase::kSums;
                break;
            }
            case Phase::kSums: {
                if (!mailbox_.Reduce(exchange_, kSumsStage, &sums)) return;
                OnSums(sums);
                break;
            }
        }
    }
}

bool LobpcgParticipant::Setup(const std::vector<double>& sums) {
    if (!ReadSetupSums(sums, problem_.rows.d, settings_, &verdict_)) {
        Finish(DistributedVerdict::Status::kNotCritical);
        return false;
    }
    if (3 * X_.cols() > static_cast<Eigen::Index>(sums[kSetupDimension])) {  // [X W P] cannot fit
        Finish(DistributedVerdict::Status::kNotConverged);
        return false;
    }
    progress_.scale = sums[kSRowSum];
    limit_ = settings_.lobpcg.tolerance * progress_.scale;
    // Block Jacobi: (S_kk + tau I)^{-1}, the smallest tau of the sequence that factorises.
    factor_ = std::make_unique<Factor>();
    factor_->llt.setMode(Eigen::CholmodSimplicialLLt);  // LL^T fails on indefinite blocks
    // A failed shift is expected here: CHOLMOD's warning would go to stdout, where a robot
    // process writes its JSON report (`solve --transport tcp` could not read it).
    factor_->llt.cholmod().print = 0;
    double tau = settings_.lobpcg.shift_relative * progress_.scale;
    for (int attempt = 0; attempt < kMaxShiftAttempts; ++attempt) {
        Eigen::SparseMatrix<double> A = problem_.rows.own;
        for (Eigen::Index i = 0; i < A.rows(); ++i) A.coeffRef(i, i) += tau;
        factor_->llt.compute(A);
        if (factor_->llt.info() == Eigen::Success) break;
        tau *= settings_.lobpcg.shift_growth;
    }
    CERTISLAM_CHECK(factor_->llt.info() == Eigen::Success);  // tau far above ||S|| factorises
    progress_.shift = tau;
    return true;
}

std::vector<double> LobpcgParticipant::PartialSums() {
    std::vector<double> out;
    switch (purpose_) {
        case Purpose::kStart:
            AX_ = product_;
            PackUpper(X_.transpose() * X_, &out);
            PackUpper(X_.transpose() * AX_, &out);
            break;
        case Purpose::kIterate: {
            AW_ = product_;
            const Eigen::Index n = X_.rows();
            Eigen::MatrixXd Z(n, X_.cols() + W_.cols() + P_.cols());
            Eigen::MatrixXd AZ(n, Z.cols());
            Z << X_, W_, P_;
            AZ << AX_, AW_, AP_;
            PackUpper(Z.transpose() * Z, &out);
            PackUpper(Z.transpose() * AZ, &out);
            out.insert(out.end(), residual_sq_.begin(), residual_sq_.end());
            break;
        }
        case Purpose::kVerify:
        case Purpose::kFinalVerify: {
            AX_ = product_;
            const Eigen::MatrixXd R = AX_ - X_ * theta_.asDiagonal();
            out = {X_.col(0).squaredNorm(), X_.col(0).dot(AX_.col(0)), R.col(0).squaredNorm()};
            break;
        }
    }
    return out;
}

void LobpcgParticipant::OnSums(const std::vector<double>& sums) {
    const Eigen::Index m = X_.cols();
    if (purpose_ == Purpose::kStart) {
        size_t from = 0;
        gram_ = LobpcgGram{};
        gram_.x = static_cast<int>(m);
        if (sums.size() != static_cast<size_t>(m * (m + 1))) {
            return Finish(DistributedVerdict::Status::kInconsistent);
        }
        gram_.gram = UnpackUpper(sums, m, &from);
        gram_.s_gram = UnpackUpper(sums, m, &from);
        const RayleighRitzResult rr =
            SolveRayleighRitz(gram_, static_cast<int>(m), settings_.lobpcg.drop_tolerance);
        if (!rr.ok) return Finish(DistributedVerdict::Status::kNotConverged);
        X_ = X_ * rr.coefficients;
        AX_ = AX_ * rr.coefficients;
        theta_ = rr.ritz_values;
        active_.assign(static_cast<size_t>(m), true);
        return Iterate();
    }
    if (purpose_ == Purpose::kIterate) return OnIterationSums(sums);
    if (sums.size() != 3) return Finish(DistributedVerdict::Status::kInconsistent);
    // The exact Rayleigh quotient; ||S x - lambda x|| <= ||S x - theta x||.
    verdict_.lambda_min = sums[1] / sums[0];
    verdict_.residual_estimate = std::sqrt(sums[2] / sums[0]);
    ritz_ = X_.col(0) / std::sqrt(sums[0]);
    if (verdict_.residual_estimate <= limit_) return Finish(DistributedVerdict::Status::kConverged);
    if (purpose_ == Purpose::kFinalVerify) return Finish(DistributedVerdict::Status::kNotConverged);
    if (refresh_) {  // AX_ is exact now (PartialSums); X_ and theta_ are the last Ritz pairs
        refresh_ = false;
        P_.resize(X_.rows(), 0);
        AP_.resize(X_.rows(), 0);
        ++progress_.restarts;
    } else if (!Update()) {
        return Finish(DistributedVerdict::Status::kNotConverged);
    }
    Iterate();
}

void LobpcgParticipant::OnIterationSums(const std::vector<double>& sums) {
    const Eigen::Index m = X_.cols();
    gram_ = LobpcgGram{};
    gram_.x = static_cast<int>(m);
    gram_.w = static_cast<int>(W_.cols());
    gram_.p = static_cast<int>(P_.cols());
    const Eigen::Index s = gram_.x + gram_.w + gram_.p;
    if (sums.size() != static_cast<size_t>(s * (s + 1) + m)) {
        return Finish(DistributedVerdict::Status::kInconsistent);
    }
    size_t from = 0;
    gram_.gram = UnpackUpper(sums, s, &from);
    gram_.s_gram = UnpackUpper(sums, s, &from);
    Eigen::VectorXd residual(m);
    for (Eigen::Index j = 0; j < m; ++j) residual(j) = std::sqrt(sums[from + j]);
    if (residual(0) <= limit_) return Verify(false);  // on the recurrence: check exactly
    // The recurrences for S X and S P drift from the exact products (LOBPCG's known instability,
    // Hetmaniuk and Lehoucq 2006): a residual that stopped falling restarts from an exact S X
    // without P. Every robot decides it from the same sums.
    if (stalled_ == 0 || residual(0) < 0.5 * best_residual_) {
        best_residual_ = residual(0);
        stalled_ = 1;
    } else if (++stalled_ > kStallIterations) {
        stalled_ = 0;
        refresh_ = true;
        return Verify(false);
    }
    for (Eigen::Index j = 1; j < m; ++j) active_[static_cast<size_t>(j)] = residual(j) > limit_;
    if (!Update()) return Verify(true);
    Iterate();
}

void LobpcgParticipant::Iterate() {
    if (progress_.iterations >= settings_.lobpcg.max_iterations) return Verify(true);
    ++progress_.iterations;
    ++exchange_;
    const Eigen::MatrixXd R = AX_ - X_ * theta_.asDiagonal();
    residual_sq_.clear();
    for (Eigen::Index j = 0; j < R.cols(); ++j) residual_sq_.push_back(R.col(j).squaredNorm());
    std::vector<Eigen::Index> active;
    for (Eigen::Index j = 0; j < R.cols(); ++j) {
        if (active_[static_cast<size_t>(j)]) active.push_back(j);
    }
    W_ = factor_->llt.solve(Eigen::MatrixXd(R(Eigen::all, active)));  // Knyazev: W = T R
    SendBlock(W_, Purpose::kIterate);
    phase_ = Phase::kProduct;
}

void LobpcgParticipant::Verify(bool final) {
    ++exchange_;
    SendBlock(X_, final ? Purpose::kFinalVerify : Purpose::kVerify);
    phase_ = Phase::kProduct;
}

bool LobpcgParticipant::Update() {
    const int m = gram_.x;
    const RayleighRitzResult rr = SolveRayleighRitz(gram_, m, settings_.lobpcg.drop_tolerance);
    if (!rr.ok) return false;
    if (rr.dropped_p) ++progress_.restarts;
    const Eigen::MatrixXd& C = rr.coefficients;
    Eigen::MatrixXd P = W_ * C.middleRows(m, gram_.w);
    Eigen::MatrixXd AP = AW_ * C.middleRows(m, gram_.w);
    if (gram_.p > 0) {
        P += P_ * C.bottomRows(gram_.p);
        AP += AP_ * C.bottomRows(gram_.p);
    }
    X_ = X_ * C.topRows(m) + P;
    AX_ = AX_ * C.topRows(m) + AP;
    P_ = std::move(P);
    AP_ = std::move(AP);
    theta_ = rr.ritz_values;
    return true;
}

void LobpcgParticipant::Finish(DistributedVerdict::Status status) {
    verdict_.status = status;
    verdict_.steps = exchanges_done_;
    done_ = true;
    mailbox_.Clear();
}

}  // namespace certislam::certify
