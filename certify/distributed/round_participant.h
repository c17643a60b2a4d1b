// One robot's share of a distributed certificate round, whichever eigen-solver runs it: the
// verdict every robot reaches, and the message-driven interface the certifier actor drives.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <utility>
#include <vector>

#include "certify/distributed/distributed_certificate.h"
#include "slam/core/pose_graph.h"

namespace certislam::certify {

struct LanczosSettings;

/// What one robot's share of a round computed (identical on every robot of the round): the
/// team's sums at one X on one graph and the eigen-solver's lambda_min. The verdict and bound
/// follow from them by the central rules (DecideRound in round_certificate.h).
struct DistributedVerdict {
    enum class Status {
        kConverged,     ///< critical, and the Ritz value of lambda_min converged
        kNotCritical,   ///< gradient above tolerance (FirstOrderVerdict): no eigenvalue
        kNotConverged,  ///< the solver ran out of steps (lambda_min: best Ritz value)
        kInconsistent,  ///< a neighbour's entries did not cover the poses this robot reads
    };
    Status status = Status::kNotConverged;
    std::uint64_t round = 0;          ///< the anchor's round id
    double lambda_min = 0.0;          ///< smallest Ritz value of S
    double residual_estimate = 0.0;   ///< residual of the Ritz pair (the solver's own estimate)
    double q_norm = 0.0;              ///< max absolute row sum of Q (team)
    double eta = 0.0;                 ///< eta_relative * q_norm
    double cost = 0.0;                ///< f(X) = tr(X Q X^T) (team)
    double dual_value = 0.0;          ///< tr(Lambda) (team)
    double gradient_norm = 0.0;       ///< ||2 X S||_F (team)
    double gradient_tolerance = 0.0;  ///< absolute first-order tolerance (FirstOrderVerdict)
    double x_norm = 0.0;              ///< ||X||_F (team)
    double objective_noise = 0.0;     ///< rounding floor of f(X) (team; ObjectiveOfColumns)
    int poses = 0;                    ///< poses of the round's graph
    /// Neighbour exchanges of the round: Lanczos steps (one S v each), LOBPCG exchanges (one
    /// block of S v each)
    int steps = 0;
    double entries_sent = 0.0;  ///< doubles of v this robot sent to neighbours
    /// Anchor with CertifierConfig::cross_check: lambda_min of the round's joint graph by the
    /// centralised check (certify::Certify), for comparison
    std::optional<double> central_lambda_min;
};

/// Drives one robot through a round: Begin(), then feed every CertificateVector and
/// CertificateReduction of the round; Done() once the verdict is in.
class RoundParticipant {
  public:
    /// Sends this robot's public entries of one vector of the round to its neighbours.
    using VectorSender = std::function<void(int step, const std::vector<slam::PoseId>& ids,
                                            const Eigen::VectorXd& values)>;
    /// Sends this robot's partial sums of (step, stage) to every robot.
    using ReductionSender =
        std::function<void(int step, int stage, const std::vector<double>& values)>;

    virtual ~RoundParticipant() = default;
    /// Sends the setup sums (call once, after the handlers are in place).
    virtual void Begin() = 0;
    /// A neighbour's public entries of vector `step`.
    virtual void OnVector(int robot, int step, const std::vector<slam::PoseId>& ids,
                          const Eigen::VectorXd& values) = 0;
    /// A robot's partial sums of (step, stage).
    virtual void OnReduction(int robot, int step, int stage, const std::vector<double>& values) = 0;
    /// True once the verdict is in.
    virtual bool Done() const = 0;
    /// The verdict (meaningful once Done()).
    virtual const DistributedVerdict& Verdict() const = 0;
    /// This robot's segment of the Ritz vector of lambda_min (zero before the first estimate).
    virtual Eigen::VectorXd RitzSegment() const = 0;
};

/// The setup sums every participant reduces first (step 0, stage 0): the team's first-order
/// quantities at the round's X, in this order, then the method's own.
enum SetupSum {
    kSetupCost,            ///< f(X), summed
    kSetupGradientSq,      ///< ||2 X S||_F^2, summed
    kSetupQRowSum,         ///< ||Q||_inf, the maximum over robots
    kSetupTraceLambda,     ///< tr(Lambda), summed
    kSetupDimension,       ///< rows of S, summed
    kSetupXNormSq,         ///< ||X||_F^2, summed
    kSetupObjectiveNoise,  ///< f's rounding floor, summed
    kSetupShared           ///< the first method-specific sum
};

/// This robot's setup shares: the first-order quantities of `problem`, then `extra`.
std::vector<double> SetupShares(const LocalCertificateProblem& problem,
                                const std::vector<double>& extra);

/// Reads the team's setup sums into `v` (cost, tr(Lambda), norms, poses) and applies the
/// centralised check's first-order rule (FirstOrderVerdict), setting eta and the gradient
/// tolerance; false at a non-critical X (no eigenvalue can make a verdict there).
bool ReadSetupSums(const std::vector<double>& sums, int d, const LanczosSettings& settings,
                   DistributedVerdict* v);

/// A neighbour's public entries of one vector (or block) message: its pose ids and values.
using NeighborEntries = std::pair<std::vector<slam::PoseId>, Eigen::VectorXd>;

/// The messages of a round a participant holds until it uses them: neighbours' public entries by
/// step and every robot's partial sums by (step, stage), its own included.
class RoundMailbox {
  public:
    RoundMailbox(int robot, std::vector<int> team, std::set<int> neighbor_robots);

    /// Keeps a neighbour's entries of vector `step` (a non-neighbour's, or a step before
    /// `current`, is dropped).
    void PutVector(int robot, int step, int current, const std::vector<slam::PoseId>& ids,
                   const Eigen::VectorXd& values);
    /// Keeps another robot's partial sums of (step, stage) (a step before `current`: dropped).
    void PutPartial(int robot, int step, int stage, int current, const std::vector<double>& values);
    /// Keeps this robot's own partial sums of (step, stage).
    void PutOwn(int step, int stage, const std::vector<double>& values);
    /// The team's sums of (step, stage), added in team order so that every robot gets the same
    /// bits, the maximum at indices `max_at`; false until every robot's partial sums are in.
    bool Reduce(int step, int stage, std::vector<double>* sums,
                const std::vector<std::size_t>& max_at = {});
    /// Every neighbour's entries of vector `step` by robot; nullptr until all are in.
    std::map<int, NeighborEntries>* Vectors(int step);
    /// Forgets vector `step`'s entries.
    void EraseVectors(int step) { vectors_.erase(step); }
    /// Forgets everything (the round is over).
    void Clear();

  private:
    int robot_;
    std::vector<int> team_;
    std::set<int> neighbor_robots_;
    std::map<int, std::map<int, NeighborEntries>> vectors_;  ///< step -> robot -> entries
    std::map<std::pair<int, int>, std::map<int, std::vector<double>>> partials_;
};

/// The neighbours' entries of a `cols`-column block at problem.neighbor_ids (b rows per pose, in
/// that order) from their messages, whose values hold the block's columns one after another;
/// false when a message does not cover a pose this robot reads.
bool GatherNeighborEntries(const LocalCertificateProblem& problem,
                           const std::map<int, NeighborEntries>& vectors, Eigen::Index cols,
                           Eigen::MatrixXd* out);

/// The participant `settings.method` names (LanczosParticipant or LobpcgParticipant).
std::unique_ptr<RoundParticipant> MakeRoundParticipant(
    LocalCertificateProblem problem, std::vector<int> team, std::uint64_t round,
    const LanczosSettings& settings, RoundParticipant::VectorSender send_vector,
    RoundParticipant::ReductionSender send_reduction);

}  // namespace certislam::certify
