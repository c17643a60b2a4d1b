// Certifier actor. Distributed mode (default): when the team anchor (lowest robot id) has every
// robot's converged bundle it opens a round naming them; every robot's certifier builds its own
// rows of S and the certifiers run Lanczos together, exchanging only the entries of v at public
// poses and partial sums, so every robot reaches lambda_min and the team's sums (cost, tr(Lambda),
// gradient) of one X on one graph; the anchor decides by the central rule (certify::DecideRound:
// the PSD test of S + e D of the round's graph proves the bound). Centralised
// mode: the anchor assembles the joint Q and X and checks alone. Either way the anchor reports the
// verdict to every robot's solver and, at a saddle, sends each robot its block at rank r+1
// (Riemannian staircase, computed centrally at the anchor).
#pragma once

#include <atomic>
#include <chrono>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <vector>

#include "actors/certifier_bundles.h"
#include "actors/convert.h"
#include "actors/node_actor.h"
#include "certify/certificate.h"
#include "certify/distributed/distributed_lanczos.h"
#include "certislam/v1/rbcd.pb.h"

namespace certislam::actors {

/// Settings of the certifier actor.
struct CertifierConfig {
    certify::CertificateConfig certificate;  ///< the check
    int max_staircase_steps = 3;             ///< saddle escapes at most, >= 0
    std::chrono::milliseconds period{200};   ///< checks at most this often, > 0
    bool distributed = true;  ///< every robot's rows of S, S*v between neighbours; false: anchor
    /// The distributed eigen-solver: block-Jacobi preconditioned LOBPCG by default (a few times
    /// fewer neighbour exchanges than Lanczos on every benchmark graph, BENCHMARKS.md).
    certify::LanczosSettings lanczos = [] {
        certify::LanczosSettings s;
        s.method = certify::LanczosSettings::Method::kLobpcg;
        return s;
    }();
    std::chrono::milliseconds round_timeout{5000};  ///< a round silent this long: the anchor
                                                    ///< checks that graph centrally
    std::chrono::milliseconds round_resend{500};    ///< a round silent this long: last messages
                                                    ///< re-sent (a peer may have joined late)
    bool cross_check =
        false;  ///< anchor, distributed: also checks every round's graph
                ///< centrally (certify::DistributedVerdict::central_lambda_min; tests)
    /// After a certified verdict no new check opens while the graph (every edge), the rank and
    /// the pose ids are those certified and no robot's block moved more than this, relative to
    /// the block's Frobenius norm, from its certified value (the certified lower bound on f*
    /// depends on the graph only). >= 0; 0: any move re-checks.
    double settled_move_relative = 1e-6;

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// Distributed-solution certifier. Its CertificateReport's `path` says which check gave the
/// verdict: a distributed round, the anchor's centralised check (centralised mode), or the
/// anchor's centralised check of a round that stayed silent for round_timeout or whose
/// eigen-solve ran out of steps without a verdict (fallback).
class CertifierActor final : public NodeActor {
  public:
    CertifierActor(zmq::context_t& context, TeamWiring wiring, CertifierConfig config);
    ~CertifierActor() override { Stop(); }

    /// Certificates computed here so far.
    int Checks() const { return checks_.load(); }
    /// Saddle escapes sent so far.
    int Escapes() const { return escapes_.load(); }
    /// Distributed rounds this robot finished.
    int Rounds() const { return rounds_.load(); }
    /// Bytes of other robots' bundles this certifier received (counted here, in
    /// BytesSentToPeers() too: the publisher cannot tell its subscribers apart).
    std::uint64_t BundleBytesFromPeers() const { return bundle_bytes_.load(); }
    /// Anchor: rounds checked centrally instead: abandoned for a silent robot, or ended
    /// inconclusive because their eigen-solve ran out of steps.
    int Fallbacks() const { return fallbacks_.load(); }
    /// Lanczos steps (S v products, each one neighbour exchange and two sums) of every round
    /// this robot finished.
    std::uint64_t LanczosSteps() const { return lanczos_steps_.load(); }
    /// Wall seconds of every round this robot finished, from its share's start to its verdict
    /// (the anchor's decision after it not included).
    double RoundSeconds() const { return 1e-6 * static_cast<double>(round_us_.load()); }
    /// Anchor: changed bundles not re-checked because they stayed at a certified solution
    /// (CertifierConfig::settled_move_relative).
    int SettledSkips() const { return skipped_.load(); }
    /// The verdict of the last distributed round this robot finished (thread-safe).
    std::optional<certify::DistributedVerdict> LastVerdict() const {
        std::lock_guard lock(verdict_mutex_);
        return verdict_;
    }
    /// Anchor: the certificate it last reported: a distributed round's, decided by the central
    /// rule (certify::DecideRound) on the round's graph, or its own central check's (centralised
    /// mode, or the fallback after a round without a verdict) (thread-safe).
    std::optional<certify::CertificateResult> LastCertificate() const {
        std::lock_guard lock(verdict_mutex_);
        return certificate_;
    }

  protected:
    void OnStart() override;
    void OnStop() override { CloseEndpoints(); }

  private:
    using Bundle = CertifierBundle;
    bool SettledSinceCertified() const;
    void NoteVerdict(bool certified, const std::map<int, Bundle>& bundles);
    void SubscribeBundles();
    void ReadBundlesOf(int robot);
    void Tick();
    bool Assemble(slam::PoseGraph* graph, Eigen::MatrixXd* X) const {
        return Assemble(bundles_, graph, X);
    }
    bool Assemble(const std::map<int, Bundle>& bundles, slam::PoseGraph* graph,
                  Eigen::MatrixXd* X) const {
        return AssembleBundles(bundles, Wiring().robots.size(), graph, X);
    }
    /// The anchor's central check of `graph` at `X`, assembled from `bundles` (whose verdict it
    /// records and which an escape splits).
    void CheckCentrally(const slam::PoseGraph& graph, const Eigen::MatrixXd& X,
                        v1::CertificatePath path, const std::map<int, Bundle>& bundles);
    /// Records `result` as the verdict (LastCertificate(), NoteVerdict) and sends its report: rank
    /// r, the graph's edge count `edges`, the path that decided it.
    void Publish(const certify::CertificateResult& result, std::uint32_t rank, std::uint64_t edges,
                 v1::CertificatePath path, const std::map<int, Bundle>& bundles);
    void Escape(const Eigen::SparseMatrix<double>& Q, const Eigen::MatrixXd& X,
                const Eigen::VectorXd& v, double gradient_tolerance,
                const std::map<int, Bundle>& bundles);
    // Distributed rounds.
    void SubscribeRounds();
    void StartRound();
    void OnRound(const v1::CertificateRound& round);
    void Deliver(const transport::Message& m);
    void RoundFinished();
    void ResendIfStalled();

    CertifierConfig config_;
    bool anchor_ = false;
    transport::Endpoint* out_ = nullptr;
    std::map<int, Bundle> pending_;                       ///< bundles being received
    std::map<int, Bundle> bundles_;                       ///< last complete bundle per robot
    std::map<int, std::vector<Bundle>> history_;          ///< recent distinct bundles, newest last
    std::map<int, Bundle> round_bundles_;                 ///< anchor: the bundles of the round
    std::set<int> bundle_streams_;                        ///< robots whose bundle stream it reads
    std::unique_ptr<certify::RoundParticipant> lanczos_;  ///< the round in progress
    std::uint64_t round_ = 0;                             ///< its id
    std::uint64_t round_edges_ = 0;                       ///< edges of its graph
    std::uint32_t round_rank_ = 0;                        ///< its relaxation rank
    std::uint64_t rounds_opened_ = 0;                     ///< anchor: rounds opened
    std::chrono::steady_clock::time_point round_progress_{};  ///< last message of the round
    std::chrono::steady_clock::time_point round_opened_{};    ///< anchor: when it opened
    bool round_heard_ = false;  ///< a message of another robot for the round arrived
    /// anchor: when the first of a run of reopened (stalled) rounds opened
    std::optional<std::chrono::steady_clock::time_point> stalled_since_;
    std::chrono::steady_clock::time_point round_resent_{};  ///< last re-send of a stall
    std::vector<transport::Message> round_sent_;   ///< round opening, last vector, last sums
    std::optional<v1::CertificateRound> waiting_;  ///< a round whose bundles are not all here
    std::map<std::uint64_t, std::vector<transport::Message>> early_;  ///< rounds not begun
    std::atomic<int> rounds_{0};
    std::atomic<int> fallbacks_{0};
    std::atomic<std::uint64_t> bundle_bytes_{0};
    mutable std::mutex verdict_mutex_;
    std::optional<certify::DistributedVerdict> verdict_;
    std::optional<certify::CertificateResult> certificate_;  ///< anchor: the last one reported
    bool dirty_ = false;
    /// anchor: the bundles of the last verdict when it was certified (empty otherwise)
    std::map<int, Bundle> certified_bundles_;
    std::atomic<int> skipped_{0};
    std::atomic<std::uint64_t> lanczos_steps_{0};
    std::atomic<std::uint64_t> round_us_{0};               ///< RoundSeconds() in microseconds
    std::chrono::steady_clock::time_point round_began_{};  ///< this robot's share of the round
    int level_ = 0;
    std::atomic<int> checks_{0};
    std::atomic<int> escapes_{0};
};

}  // namespace certislam::actors
