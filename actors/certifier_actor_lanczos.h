// One robot's side of the distributed certificate over the network: its rows of S (built from
// the edges at its poses and its neighbours' poses at their ends) and a Lanczos iteration driven
// by messages (neighbours' public entries of v, every robot's partial sums), so that every robot
// reaches the same lambda_min and verdict. No sockets here: the certifier actor moves the messages.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <set>
#include <utility>
#include <vector>

#include "certify/distributed/distributed_certificate.h"
#include "slam/core/loop_closure.h"

namespace certislam::actors {

/// Settings of the distributed check (the centralised check's meaning of every tolerance).
struct LanczosSettings {
    /// Lanczos steps at most (and at most the dimension of S), >= 2. Without shift-invert the
    /// smallest eigenvalue of S sits in a cluster near 0 far below ||S||: Lanczos may need
    /// nearly the whole Krylov space, which full reorthogonalisation makes exact.
    int max_krylov = 5000;
    double tolerance = 1e-10;                   ///< Ritz residual <= this * max |Ritz value|
    int check_every = 5;                        ///< Ritz values computed every this many steps
    std::uint64_t seed = 20261121;              ///< start vector seed (robot id added)
    double eta_relative = 1e-7;                 ///< certified: lambda_min >= -eta_relative ||Q||
    double gradient_tolerance_relative = 1e-4;  ///< critical: ||grad|| <= this 2 sqrt(||Q|| f)
};

/// What one robot concluded from a round (identical on every robot of the round).
struct DistributedVerdict {
    enum class Status {
        kCertified,     ///< critical and lambda_min >= -eta
        kNotCertified,  ///< critical, lambda_min < -eta: a saddle
        kNotCritical,   ///< gradient above tolerance: no verdict
        kNotConverged,  ///< Lanczos ran out of steps (lambda_min: best Ritz value)
        kInconsistent,  ///< a neighbour's entries did not cover the poses this robot reads
    };
    Status status = Status::kNotConverged;
    std::uint64_t round = 0;          ///< the anchor's round id
    double lambda_min = 0.0;          ///< smallest Ritz value of S
    double residual_estimate = 0.0;   ///< |beta_m y_m| of the Ritz pair
    double q_norm = 0.0;              ///< max absolute row sum of Q (team)
    double eta = 0.0;                 ///< eta_relative * q_norm
    double cost = 0.0;                ///< f(X) = tr(X Q X^T) (team)
    double dual_value = 0.0;          ///< tr(Lambda) (team)
    double gradient_norm = 0.0;       ///< ||2 X S||_F (team)
    double gradient_tolerance = 0.0;  ///< absolute first-order tolerance
    int steps = 0;                    ///< Lanczos steps (S v products)
    double entries_sent = 0.0;        ///< doubles of v this robot sent to neighbours
    /// Anchor with CertifierConfig::cross_check: lambda_min of the round's joint graph by the
    /// centralised check (certify::Certify), for comparison
    std::optional<double> central_lambda_min;
};

/// A robot's view of the joint graph for its rows of S.
struct LocalCertificateProblem {
    int robot = 0;                           ///< this robot
    certify::CertificateRows rows;           ///< own poses first, then neighbours' (local order)
    std::vector<slam::PoseId> public_ids;    ///< ids of rows.public_poses
    std::vector<slam::PoseId> neighbor_ids;  ///< ids of rows.neighbor_poses
    std::set<int> neighbor_robots;           ///< robots whose entries of v it reads
    double cost = 0.0;                       ///< own columns' share of tr(X Q X^T)
    double gradient_sq = 0.0;                ///< own columns' share of ||2 X S||_F^2
    double q_row_sum = 0.0;                  ///< largest absolute row sum of Q's own rows
};

/// Builds robot `robot`'s problem from its poses' block (`own_ids` in index order, X_own r x 4n),
/// every edge with an end at its poses, and the neighbours' blocks at the other ends (r x 4).
/// Returns false when an edge's far end has no block.
bool MakeLocalProblem(int robot, const std::vector<slam::PoseId>& own_ids,
                      const Eigen::MatrixXd& X_own, const std::vector<slam::LoopClosure>& edges,
                      const std::map<slam::PoseId, Eigen::MatrixXd>& neighbor_blocks,
                      LocalCertificateProblem* out);

/// Drives one robot through a round: Begin(), then feed every CertificateVector and
/// CertificateReduction of the round; Done() once the verdict is in. Two exchanges per Lanczos
/// step: alpha = v^T S v, then (after the three-term recurrence) one full reorthogonalisation
/// pass's sums c = V^T u with ||u||^2, sent together with the public entries of u (the
/// CertificateVector of step k + 1): every reader finishes the next vector itself as
/// (u - V c) / beta from the reduced sums and the public entries of V it already holds. Ritz
/// values by bisection (O(m) per check). A round whose gradient is above tolerance ends after
/// the setup sums (kNotCritical, no steps).
class LanczosParticipant {
  public:
    /// Sends this robot's public entries of the step's vector to its neighbours.
    using VectorSender = std::function<void(int step, const std::vector<slam::PoseId>& ids,
                                            const Eigen::VectorXd& values)>;
    /// Sends this robot's partial sums of (step, stage) to every robot.
    using ReductionSender =
        std::function<void(int step, int stage, const std::vector<double>& values)>;

    LanczosParticipant(LocalCertificateProblem problem, std::vector<int> team, std::uint64_t round,
                       const LanczosSettings& settings, VectorSender send_vector,
                       ReductionSender send_reduction);

    /// Sends the setup sums (call once, after the handlers are in place).
    void Begin();
    /// A neighbour's public entries of step `step`'s vector.
    void OnVector(int robot, int step, const std::vector<slam::PoseId>& ids,
                  const Eigen::VectorXd& values);
    /// A robot's partial sums of (step, stage).
    void OnReduction(int robot, int step, int stage, const std::vector<double>& values);

    /// True once the verdict is in.
    bool Done() const { return done_; }
    /// The verdict (meaningful once Done()).
    const DistributedVerdict& Verdict() const { return verdict_; }

  private:
    enum class Phase { kSetup, kProduct, kPass1, kPass2 };
    void Advance();
    bool Reduced(int step, int stage, std::vector<double>* sums, bool max_of_third = false);
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
    std::vector<double> pending_c_;  ///< second-pass sums that finish step_'s vector
    double pending_b_ = 1.0;         ///< and its norm
    /// robot -> its public entries of every finished Lanczos vector (to finish the next one)
    std::map<int, std::vector<Eigen::VectorXd>> neighbor_basis_;
    /// step -> robot -> (ids, values)
    std::map<int, std::map<int, std::pair<std::vector<slam::PoseId>, Eigen::VectorXd>>> vectors_;
    /// (step, stage) -> robot -> partial sums
    std::map<std::pair<int, int>, std::map<int, std::vector<double>>> partials_;
};

}  // namespace certislam::actors
