// The distributed eigenvalue check, one implementation: a Lanczos iteration on S = Q - Lambda(X)
// cut at every exchange, so that messages drive it (neighbours' public entries of v, every
// robot's partial sums) and every robot reaches the same lambda_min and verdict. Plain data in
// and out: the certifier actor moves the messages over the network, DistributedMinEigenpair
// moves them in memory.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <utility>
#include <vector>

#include "certify/certificate.h"
#include "certify/distributed/distributed_certificate.h"
#include "certify/distributed/distributed_lobpcg.h"
#include "certify/distributed/round_participant.h"
#include "slam/core/pose_graph.h"

namespace certislam::certify {

/// Settings of the distributed check (the centralised check's meaning of every tolerance).
struct LanczosSettings {
    /// The eigen-solver of a round (MakeRoundParticipant): every robot must use the same.
    /// LOBPCG by default: on every benchmark graph the robots certify, it needs fewer exchanges
    /// and bytes than Lanczos, whose smallest eigenvalue sits in a cluster near 0.
    enum class Method {
        kLanczos,  ///< LanczosParticipant (the fields below)
        kLobpcg,   ///< LobpcgParticipant (`lobpcg`; eta and gradient fields from here)
    };
    Method method = Method::kLobpcg;
    LobpcgSettings lobpcg;  ///< settings of the LOBPCG method
    /// Lanczos steps at most (and at most the dimension of S), >= 2. Without shift-invert the
    /// smallest eigenvalue of S sits in a cluster near 0 far below ||S||: Lanczos may need
    /// nearly the whole Krylov space, which full reorthogonalisation makes exact.
    int max_krylov = 5000;
    double tolerance = 1e-10;       ///< Ritz residual <= this * max |Ritz value|
    int check_every = 5;            ///< Ritz values computed every this many steps
    std::uint64_t seed = 20261121;  ///< start vector seed (robot id added)
    /// The certificate's first-order rule (FirstOrderVerdict): a round at a non-critical X
    /// spends no Lanczos step. The certifier actor copies its CertificateConfig here.
    double eta_relative = 1e-7;
    double gradient_tolerance_relative = 1e-4;  ///< CertificateConfig's, copied likewise

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// The round's sums as the central verdict's first-order quantities.
CertificateQuantities QuantitiesOf(const DistributedVerdict& v);

/// Drives one robot through a round: Begin(), then feed every CertificateVector and
/// CertificateReduction of the round; Done() once the verdict is in. Two exchanges per Lanczos
/// step: alpha = v^T S v, then (after the three-term recurrence) one full reorthogonalisation
/// pass's sums c = V^T u with ||u||^2, sent together with the public entries of u (the
/// CertificateVector of step k + 1): every reader finishes the next vector itself as
/// (u - V c) / beta from the reduced sums and the public entries of V it already holds. Ritz
/// values by bisection (O(m) per check), the Ritz vector by inverse iteration. A round whose
/// gradient is above tolerance ends after the setup sums (kNotCritical, no steps).
class LanczosParticipant : public RoundParticipant {
  public:
    LanczosParticipant(LocalCertificateProblem problem, std::vector<int> team, std::uint64_t round,
                       const LanczosSettings& settings, VectorSender send_vector,
                       ReductionSender send_reduction);

    /// Sends the setup sums (call once, after the handlers are in place).
    void Begin() override;
    /// A neighbour's public entries of step `step`'s vector.
    void OnVector(int robot, int step, const std::vector<slam::PoseId>& ids,
                  const Eigen::VectorXd& values) override;
    /// A robot's partial sums of (step, stage).
    void OnReduction(int robot, int step, int stage, const std::vector<double>& values) override;

    /// True once the verdict is in.
    bool Done() const override { return done_; }
    /// The verdict (meaningful once Done()).
    const DistributedVerdict& Verdict() const override { return verdict_; }
    /// This robot's segment of the unit Ritz vector of lambda_min (zero before the first check).
    Eigen::VectorXd RitzSegment() const override;

  private:
    enum class Phase { kSetup, kProduct, kPass1, kPass2 };
    void Advance();
    bool Product();
    void SendVector(int step, const Eigen::VectorXd& u);
    void Share(int step, int stage, const std::vector<double>& values);
    bool Converged(double b);
    void Finish(DistributedVerdict::Status status);

    LocalCertificateProblem problem_;
    std::vector<int> team_;
    LanczosSettings settings_;
    VectorSender send_vector_;
    ReductionSender send_reduction_;
    Phase phase_ = Phase::kSetup;
    int step_ = 0;
    int max_steps_ = 0;
    bool done_ = false;
    DistributedVerdict verdict_;
    std::vector<Eigen::VectorXd> basis_;  ///< own segments of the Lanczos vectors
    Eigen::VectorXd w_;
    std::vector<double> alpha_, beta_;
    Eigen::VectorXd ritz_;  ///< Ritz vector of lambda_min in the Lanczos basis (last check)
    std::vector<double> pending_c_;  ///< second-pass sums that finish step_'s vector
    double pending_b_ = 1.0;         ///< and its norm
    /// robot -> its public entries of every finished Lanczos vector (to finish the next one)
    std::map<int, std::vector<Eigen::VectorXd>> neighbor_basis_;
    RoundMailbox mailbox_;
};

/// Message counts of a round run in memory.
struct InMemoryTraffic {
    std::set<std::pair<int, int>> exchanges;   ///< (step, 0) of every vector exchange
    std::set<std::pair<int, int>> reductions;  ///< (step, stage) of every sum over robots
    double entries = 0.0;                      ///< doubles of v sent between robots
};

/// One round over `problems` (the team: their robot ids, in this order) by the participants
/// `settings.method` names, every message delivered in memory in send order; returns the
/// participants once no message is left.
std::vector<std::unique_ptr<RoundParticipant>> RunInMemory(
    const std::vector<LocalCertificateProblem>& problems, const LanczosSettings& settings,
    InMemoryTraffic* traffic = nullptr);

/// Each robot's problem from its rows alone: poses named (owner, global index); no X, so no cost
/// and no gradient (both zero: the gradient test passes trivially).
std::vector<LocalCertificateProblem> LocalProblemsOf(const std::vector<CertificateRows>& robots);

/// Result of DistributedMinEigenpair.
struct DistributedEigenResult {
    enum class Status {
        kConverged,     ///< Ritz residual below tolerance
        kNotConverged,  ///< max_krylov steps reached first (lambda is the best Ritz value)
    };
    Status status = Status::kNotConverged;
    double lambda_min = 0.0;              ///< Rayleigh quotient of the Ritz vector
    double residual = 0.0;                ///< ||S v - lambda v|| (global)
    std::vector<Eigen::VectorXd> vector;  ///< the unit Ritz vector, one segment per robot
    int steps = 0;                        ///< Lanczos steps
    int products = 0;                     ///< S v products (steps and the residual's)
    int vector_exchanges = 0;   ///< rounds of public entries sent (the last step sends its next)
    int scalar_reductions = 0;  ///< sums over robots of one or more scalars
    double entries_exchanged = 0.0;  ///< doubles of v sent between robots, all exchanges
};

/// Smallest eigenpair of S held as rows by robots: one LanczosParticipant per robot, their
/// messages delivered in memory (the certifier actor sends the same ones over the network).
/// The rows carry no X, so no gradient test is made; `settings` eta and gradient fields unused,
/// and `settings.method` too (always Lanczos: DistributedLobpcg runs the other).
DistributedEigenResult DistributedMinEigenpair(const std::vector<CertificateRows>& robots,
                                               const LanczosSettings& settings = {});

}  // namespace certislam::certify
