// One robot's message-driven share of the distributed LOBPCG (distributed_lobpcg.h), cut at every
// exchange like LanczosParticipant, so that the certifier actor can run either.
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <cstdint>
#include <map>
#include <memory>
#include <utility>
#include <vector>

#include "certify/distributed/distributed_lanczos.h"
#include "certify/distributed/lobpcg_rayleigh_ritz.h"
#include "certify/distributed/round_participant.h"

namespace certislam::certify {

/// Counters of one robot's round (identical on every robot but `entries`).
struct LobpcgProgress {
    int iterations = 0;            ///< LOBPCG iterations
    int exchanges = 0;             ///< neighbour exchanges (start, iterations, verifications)
    int products = 0;              ///< columns multiplied by S over those exchanges
    int reductions = 0;            ///< sums over robots (setup included)
    double scalars_reduced = 0.0;  ///< doubles this robot contributed to them
    int restarts = 0;              ///< iterations whose P was dropped
    double scale = 0.0;            ///< ||S||_inf (team)
    double shift = 0.0;            ///< tau of this robot's preconditioner
};

/// LOBPCG on S over messages. Exchange e sends the public entries of a block (the start block,
/// an iteration's W, or X to verify) as one vector message of step e, its columns one after
/// another; its one reduction is (step e, stage 1); the setup sums are (0, 0). Every robot solves
/// the same Rayleigh-Ritz problem from the same sums (summed in team order), so all take the same
/// decisions. A Ritz pair that converged on the recurrence for S X is verified with an exact
/// product before the verdict. Verdict().steps counts the exchanges whose product was taken.
class LobpcgParticipant : public RoundParticipant {
  public:
    LobpcgParticipant(LocalCertificateProblem problem, std::vector<int> team, std::uint64_t round,
                      const LanczosSettings& settings, VectorSender send_vector,
                      ReductionSender send_reduction);
    ~LobpcgParticipant() override;

    void Begin() override;
    void OnVector(int robot, int step, const std::vector<slam::PoseId>& ids,
                  const Eigen::VectorXd& values) override;
    void OnReduction(int robot, int step, int stage, const std::vector<double>& values) override;
    bool Done() const override { return done_; }
    const DistributedVerdict& Verdict() const override { return verdict_; }
    Eigen::VectorXd RitzSegment() const override;
    /// The round's counters.
    const LobpcgProgress& Progress() const { return progress_; }

  private:
    enum class Phase { kSetup, kProduct, kSums };
    enum class Purpose { kStart, kIterate, kVerify, kFinalVerify };
    struct Factor;
    void Advance();
    bool Setup(const std::vector<double>& sums);
    std::vector<double> PartialSums();
    bool Gather(Eigen::MatrixXd* neighbors);
    void OnSums(const std::vector<double>& sums);
    void OnIterationSums(const std::vector<double>& sums);
    void Iterate();
    void Verify(bool final);
    void SendBlock(const Eigen::MatrixXd& B, Purpose purpose);
    bool Update();
    void Share(int step, int stage, const std::vector<double>& values);
    void Finish(DistributedVerdict::Status status);

    LocalCertificateProblem problem_;
    std::vector<int> team_;
    LanczosSettings settings_;
    VectorSender send_vector_;
    ReductionSender send_reduction_;
    Phase phase_ = Phase::kSetup;
    Purpose purpose_ = Purpose::kStart;
    bool done_ = false;
    DistributedVerdict verdict_;
    LobpcgProgress progress_;
    std::unique_ptr<Factor> factor_;   ///< (S_kk + tau I)^{-1}
    int exchange_ = 0;                 ///< the exchange in progress
    int exchanges_done_ = 0;           ///< exchanges whose product was taken
    double limit_ = 0.0;               ///< tolerance * ||S||_inf
    Eigen::MatrixXd X_, AX_, P_, AP_;  ///< own segments; P_ empty before the first update
    Eigen::MatrixXd sent_, product_;   ///< the block of the exchange in progress and S of it
    Eigen::VectorXd theta_;            ///< Ritz values of X_
    std::vector<bool> active_;         ///< columns whose residual is above tolerance
    std::vector<double> residual_sq_;  ///< own share of ||R_j||^2 of the last W's residuals
    LobpcgGram gram_;                  ///< the last iteration's reduced Gram matrices
    Eigen::MatrixXd W_, AW_;           ///< the last iteration's W and S W
    Eigen::VectorXd ritz_;             ///< own segment of the verified unit Ritz vector
    double best_residual_ = 0.0;       ///< smallest recurrence residual since the last refresh
    int stalled_ = 0;                  ///< iterations since best_residual_ last halved
    bool refresh_ = false;             ///< the verify in progress restarts from exact S X
    RoundMailbox mailbox_;
};

}  // namespace certislam::certify
