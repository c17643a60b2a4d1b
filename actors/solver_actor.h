// RBCD solver actor: owns this robot's block (SolverState), takes keyframes and loop closures,
// exchanges public poses with its neighbours asynchronously (a silent neighbour's last known
// poses are used), warm-starts on every new edge, and hands converged blocks to the certifier.
#pragma once

#include <atomic>
#include <chrono>
#include <cstddef>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include "actors/convert.h"
#include "actors/durable_log.h"
#include "actors/node_actor.h"
#include "certify/pipeline/overlap_sweep.h"
#include "certify/pipeline/solver_state.h"
#include "certify/pipeline/team_finish.h"
#include "certify/pipeline/team_rounds.h"
#include "certislam/v1/certificate.pb.h"
#include "certislam/v1/rbcd.pb.h"
#include "slam/core/trajectory.h"

namespace certislam::actors {

/// Settings of the solver actor.
struct SolverActorConfig {
    certify::SolverConfig solver;                  ///< RBCD settings
    std::chrono::milliseconds tick{2};             ///< a block update at most this often, > 0
    std::chrono::milliseconds heartbeat{200};      ///< poses, status, loops re-sent this often
    std::chrono::milliseconds bundle_period{300};  ///< converged block to the certifier, > 0
    /// Public poses after a step at most this often while the graph grows (a later step's poses
    /// wait for the next tick past it; nothing is lost, the newest poses go out), >= 0; 0: after
    /// every step. Once the graph is final, or unchanged for SolverActor::kGraphSettled, every
    /// step's poses go out at once. While the graph grows every step moves the block: without a
    /// period the poses of every step would cross.
    std::chrono::milliseconds publish_period{50};
    std::string log_path;      ///< durable log of accepted loop closures (replayed); empty: none
    std::string log_identity;  ///< the mission identity written in a new log's header
    /// Inter-robot loops re-sent with every heartbeat (late or restarted peers learn the ones
    /// they missed); false where the source itself re-sends them to late subscribers (a pose
    /// graph's robot, whose hundreds of inter-robot edges would flood the peers' queues).
    bool rebroadcast_loops = true;
    /// Synchronous RBCD++ (certify/pipeline/team_rounds.h) once the graph is final: no block
    /// update before that, then the own block restarts from the chordal relaxation of the own
    /// edges, robots are placed in id order and sweep in rounds with Nesterov extrapolation and
    /// adaptive restart until the team's gradient is below tolerance (asynchronous RBCD after
    /// rounds.max_rounds). For a whole graph known up front (pose-graph robots); false: the
    /// asynchronous updates of a growing graph.
    bool synchronous = false;
    /// With `synchronous`: asynchronous RBCD updates while the graph grows (a live estimate for
    /// the mapper and the peers), the rounds once it is final. false: no update before final.
    bool async_until_final = false;
    certify::TeamRoundsConfig rounds;  ///< the rounds
    /// Rounds that made no progress this long, plus SolverActor::kStallPerRobot per robot of the
    /// team (peers silent), give up: asynchronous updates take over, as after rounds.max_rounds;
    /// > 0.
    std::chrono::milliseconds rounds_stall{20000};
    /// A peer's request of a kept round message (a stalled round) is answered this long after
    /// the message went out at the earliest, then at doubling intervals per peer up to
    /// SolverActor::kMaxResendWait: a request sooner is most likely for a copy still in flight
    /// on a loaded host, and a lost message costs this much more than a heartbeat. > 0.
    std::chrono::milliseconds resend_spacing{1000};
    /// Synchronous mode: from this round on, rounds whose linear rate projects their tolerance
    /// beyond rounds.max_rounds (TeamRoundsConfig::hand_over_after), and rounds that reach
    /// max_rounds, hand the team to its second-order finish (certify/pipeline/team_finish.h: a
    /// distributed trust region on the whole X with neighbour exchanges and sums only), which
    /// converges where RBCD's linear tail crawls; a finish that does not converge leaves
    /// asynchronous updates. 0: no finish (asynchronous updates after max_rounds). >= 0.
    int finish_after_rounds = 50;
    certify::TeamFinishConfig finish;  ///< the finish

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// What the solver knows now (a copy; thread-safe to take).
struct SolverSnapshot {
    int num_poses = 0;            ///< own keyframes
    bool final = false;           ///< own keyframes ended and every matcher said end of loops
    bool local_ok = false;        ///< block gradient below tolerance at the last step
    double grad_norm = 0.0;       ///< block gradient norm at the last step
    std::uint64_t steps = 0;      ///< block updates done
    int rank = 0;                 ///< relaxation rank now
    int staircase_level = 0;      ///< saddle escapes adopted
    int anchor = 0;               ///< robot whose pose 0 anchors the trajectory
    int inter_robot_loops = 0;    ///< inter-robot loops known
    slam::Trajectory trajectory;  ///< own poses in the anchor's frame, with keyframe stamps
    std::optional<v1::CertificateReport> report;    ///< last certificate heard
    std::chrono::steady_clock::time_point changed;  ///< last change of the graph or rank
    /// Own edges as the solver holds them (odometry and active loops whose tail is own, with
    /// their weights), so a caller can rebuild the team graph.
    std::vector<slam::LoopClosure> edges;
    std::uint64_t team_rounds = 0;  ///< synchronous rounds swept (SolverActorConfig::synchronous)
    int restarts = 0;               ///< adaptive restarts of those rounds
    /// Round messages this solver re-sent because a stalled peer asked for them (SolverStatus
    /// round_wants): one per message, to that peer alone
    std::uint64_t round_resends = 0;
    /// Overlapping sweeps' proposals of own poses dropped (TeamRounds::SetProposable): a
    /// neighbour proposed a pose its domain cannot hold, or a block that is not a pose
    std::uint64_t rejected_proposals = 0;
    /// Runs of the rounds whose overlapping sweeps a rise of f ended (TeamRounds::OverlapEndedAt)
    int overlap_ends = 0;
    bool rounds_converged = false;  ///< the rounds reached the team's gradient tolerance
    bool rounds_gave_up = false;    ///< the rounds hit max_rounds: asynchronous updates took over
    /// In its synchronous rounds (or their finish) now, not converged yet (not gone asynchronous)
    bool rounds_running = false;
    /// The certified state came from the durable log's checkpoint (a restart after the team
    /// certified), not from a round of this run.
    bool restored = false;
    /// The team's round session: 0 at the start, a new one each time a peer restarted and the
    /// team's rounds began again from their iterates.
    std::uint64_t round_session = 0;
    /// The team's second-order finish (SolverActorConfig::finish_after_rounds), summed over every
    /// finish this solver ran; `finish_status` is the last one's ("" none, "running",
    /// "converged", "not converged", "inconsistent").
    certify::TeamFinishProgress finish;
    int finishes = 0;
    std::string finish_status;
    std::uint64_t finish_dropped = 0;  ///< finish messages dropped before or after a finish
    double finish_seconds = 0.0;       ///< wall time in the finishes (the running one so far)
};

/// One robot's RBCD solver.
class SolverActor final : public NodeActor {
  public:
    /// A graph unchanged this long is settled: publish_period no longer holds poses back.
    static constexpr std::chrono::seconds kGraphSettled{3};

    SolverActor(zmq::context_t& context, const TeamWiring& wiring, const SolverActorConfig& config);
    ~SolverActor() override { Stop(); }

    /// The state now (thread-safe).
    SolverSnapshot Snapshot() const;

  protected:
    void OnStart() override;
    void OnStop() override { CloseEndpoints(); }

  private:
    void Subscribe();
    bool OnPublicPoses(const transport::Message& m);
    bool OnLoop(const transport::Message& m, bool replayed);
    bool NewVerdict(const std::pair<slam::PoseId, slam::PoseId>& ends, std::int64_t version,
                    bool accepted);
    void Withdraw(const std::pair<slam::PoseId, slam::PoseId>& ends);
    void Tick();
    bool IsFinal() const;
    bool InRounds() const;  ///< synchronous rounds drive the block now (not given up)
    void SyncTick();
    void AdvanceRounds();
    bool SyncAction(const certify::RoundAction& a);
    void SendRoundPoses(std::uint64_t round);
    /// Round poses to the rounds' neighbours only, each its copy (Endpoint::SendToRobot).
    void SendToNeighbours(const v1::PublicPoses& poses);
    void SendRoundSums(std::uint64_t round, double cost, double grad_norm);
    void OnRoundSums(const v1::SolverStatus& status);
    /// Applies a peer message's round session and incarnation; true when it is of this session.
    bool InSession(int robot, std::uint64_t session, std::uint64_t incarnation);
    void NewSession(std::uint64_t session);
    void StartRounds();
    /// Rounds that give up hand over to the finish (not to asynchronous updates).
    bool FinishesRounds() const;
    /// The rounds gave up (FinishesRounds): the finish from the own block now.
    void StartFinish();
    bool OnFinish(const transport::Message& m);
    /// Sends what the finish has to send (its sums fed back too), then ends it once done.
    void PumpFinish();
    void EndFinish();
    void DropFinish();
    void FeedFinish(const FinishBody& body);
    /// The finish's counters so far, with those of the finishes before.
    certify::TeamFinishProgress FinishTotals() const;
    double FinishSeconds() const;  ///< wall time in the finishes so far
    void RefreshFinishCounters();  ///< the snapshot's finish counters only (cheap, every message)
    /// Ends rounds_ (their counts kept) and its overlapping sweep.
    void DropRounds();
    /// The own poses near the neighbours (certify::BoundaryOf), kept until the graph changes.
    const certify::RoundBoundary& Boundary();
    template <typename Proto>
    void StampSession(Proto* proto) const {
        proto->set_round_session(round_session_);
        proto->set_incarnation(incarnation_);
    }
    /// The solver's status; `wants`: a stalled round's request (TeamRounds::Wants).
    void SendStatus(const std::vector<certify::RoundWant>& wants = {});
    /// A peer's request of round messages: those of this robot that it kept go to that peer
    /// alone. False when the request is malformed.
    bool AnswerWants(const v1::SolverStatus& request);
    /// A stalled round's request (Heartbeat): SendStatus with what the rounds wait for.
    void RequestStalledRound();
    void Heartbeat();
    void SendBundle();
    /// The next tick is due within `tick` (EveryUntilIdle); otherwise within kIdleTick.
    bool TickDue() const;
    static constexpr std::chrono::milliseconds kIdleTick{25};
    static constexpr std::chrono::milliseconds kFirstResend{std::chrono::seconds(1)};
    static constexpr std::chrono::milliseconds kLongestBundleWait{std::chrono::seconds(4)};
    /// No asynchronous step moved the block for bundle_period.
    bool BlockAtRest(std::chrono::steady_clock::time_point now) const;
    /// A bundle is due: local convergence, and the wait for a changed or an unchanged one passed.
    bool BundleDue(std::chrono::steady_clock::time_point now) const;
    void Publish();
    bool PublishDue() const;  ///< publish_period passed, or the graph final or settled
    void UpdateSnapshot();
    /// What a snapshot shows that a tick can change (the rest changes with the graph, `changed_`);
    /// a running finish's counters show at each of its trust-region steps.
    using SnapshotKey =
        std::tuple<std::uint64_t, std::uint64_t, std::uint64_t, bool, bool, bool, bool, bool, int,
                   double, std::chrono::steady_clock::time_point, std::uint64_t, std::uint64_t>;
    SnapshotKey KeyOfSnapshot() const;
    void Changed();
    void Replay();           ///< durable log: loops, and the last checkpoint kept for later
    void MaybeCheckpoint();  ///< a certified final state not logged yet: logged
    void TryRestore();       ///< the kept checkpoint, once the replayed graph is its graph

    SolverActorConfig config_;
    certify::SolverState state_;
    transport::Endpoint* poses_out_ = nullptr;
    transport::Endpoint* bundle_out_ = nullptr;
    std::vector<std::int64_t> stamps_ns_;
    std::map<int, double> team_cost_;  ///< robot -> its share of f, last heard
    std::set<int> loops_ended_;        ///< matchers that said end of loops
    /// sender -> ends of the loops it sent (what a counted end-of-loops marker is checked against)
    std::map<int, std::set<std::pair<slam::PoseId, slam::PoseId>>> loops_heard_;
    std::vector<slam::LoopClosure> team_loops_;  ///< every inter-robot loop heard (team frame)
    std::set<std::pair<slam::PoseId, slam::PoseId>> team_loop_ends_;
    /// Loop ends -> (newest matcher verdict version, accepted): withdrawals win over older
    /// accepts and over solvers' re-broadcasts (version 0).
    std::map<std::pair<slam::PoseId, slam::PoseId>, std::pair<std::int64_t, bool>> verdicts_;
    bool keyframes_ended_ = false;
    bool work_ = true;  ///< something changed since the last step
    bool local_ok_ = false;
    bool bundle_dirty_ = true;
    std::uint64_t steps_ = 0;
    double grad_norm_ = 0.0;
    std::chrono::steady_clock::time_point last_bundle_{};
    /// Once final, a bundle carries the own edges and the full block to every peer's certifier.
    /// Those of a block that keeps moving (asynchronous steps of a team that has not converged:
    /// it moved within bundle_period) go out ever less often, from bundle_period up to
    /// kLongestBundleWait; one at rest goes out about bundle_period after its last move; an
    /// unchanged one is re-sent after kFirstResend, then ever less often up to kLongestBundleWait
    /// (a new reader gets it at once: bundle_owed_).
    std::chrono::milliseconds moving_bundle_wait_{};
    std::chrono::milliseconds unchanged_bundle_wait_{kFirstResend};
    std::chrono::steady_clock::time_point last_move_{};  ///< of an asynchronous step
    std::size_t bundle_readers_ = 0;  ///< subscribers of the bundle stream at the last tick
    /// A new bundle reader came while the block was not locally converged: its bundle goes out
    /// as soon as it is (not a bundle_period later).
    bool bundle_owed_ = false;
    std::chrono::steady_clock::time_point last_publish_{};
    bool publish_pending_ = false;  ///< a step moved the block since the last publish
    /// Multiplies the asynchronous steps' tolerance: rounds.refine_rel_grad_tol / rel_grad_tol
    /// after an inconclusive report whose bound was too loose, back to 1 when the graph changes
    double tolerance_scale_ = 1.0;
    bool refined_ = false;       ///< this graph's refinement was tried (once per graph)
    int refine_steps_left_ = 0;  ///< steps of the refinement's budget still to take
    /// A refinement gets as many asynchronous steps per round of the rounds' refine_rounds.
    static constexpr int kRefineStepsPerRound = 5;
    /// Back to the configured tolerance once the refinement's budget is spent or a step is stuck.
    void EndRefinementWhenSpent(const certify::SolverStepResult& step);
    std::optional<v1::CertificateReport> report_;
    std::chrono::steady_clock::time_point changed_ = std::chrono::steady_clock::now();

    std::optional<certify::TeamRounds> rounds_;     ///< synchronous mode, once final
    std::optional<certify::OverlapSweep> overlap_;  ///< rounds_' overlapping sweep, from round 1
    int rounds_level_ = -1;                         ///< staircase level rounds_ belongs to
    bool rounds_converged_ = false;
    bool rounds_gave_up_ = false;
    std::uint64_t rounds_swept_ = 0;                  ///< over every level
    int rounds_restarts_ = 0;                         ///< over every level
    std::uint64_t rounds_rejected_ = 0;               ///< proposals dropped, over every level
    int rounds_overlap_ends_ = 0;                     ///< overlaps a rise ended, over every level
    std::optional<certify::RoundBoundary> boundary_;  ///< Boundary(), of the current graph
    bool overlap_mismatch_logged_ = false;  ///< a peer's other overlap depth was logged (once)
    bool proposals_logged_ = false;         ///< a dropped proposal was logged (once per actor)
    std::vector<certify::PoseBlocks> early_poses_;  ///< round poses heard before rounds_ began
    std::vector<v1::SolverStatus> early_sums_;      ///< round sums heard before rounds_ began
    /// A round message kept for a stalled peer's request, and when each peer may have it again
    /// (SolverActorConfig::resend_spacing).
    template <typename T>
    struct Kept {
        T message;
        std::chrono::steady_clock::time_point sent;
        /// peer -> (earliest next copy, the wait after it)
        std::map<int, std::pair<std::chrono::steady_clock::time_point, std::chrono::milliseconds>>
            again;
    };
    /// Sends `kept` to `peer` if its spacing allows; true when sent.
    template <typename T>
    bool SendAgain(Kept<T>* kept, int peer, std::chrono::steady_clock::time_point now);
    std::vector<Kept<v1::PublicPoses>> last_round_poses_;  ///< last two rounds', for requests
    std::vector<Kept<v1::SolverStatus>> last_round_sums_;  ///< last two rounds', for requests
    std::uint64_t round_resends_ = 0;                      ///< round messages re-sent on request
    std::chrono::steady_clock::time_point last_round_progress_{};
    std::chrono::steady_clock::time_point last_resend_{};  ///< last request of a stalled round
    std::chrono::milliseconds resend_wait_{200};           ///< the next request's wait (doubling)
    /// Requests of a stalled round are this far apart at most (Heartbeat).
    static constexpr std::chrono::milliseconds kMaxResendWait{3200};
    /// The rounds' stall allowance per robot of the team (RoundsStall).
    static constexpr std::chrono::milliseconds kStallPerRobot{1000};
    std::chrono::milliseconds RoundsStall() const;
    /// Round sessions: a peer that restarted lost its rounds, so the team opens a new session
    /// (solver_actor_rounds.cpp); the sessions only grow, and every robot joins the highest.
    std::uint64_t round_session_ = 0;
    std::uint64_t incarnation_ = 0;  ///< random, non-zero (set at construction): tells a restart
    std::map<int, std::uint64_t> incarnations_;  ///< robot -> incarnation last heard
    bool chordal_started_ = false;  ///< the first rounds began from the chordal start; later: not

    std::optional<certify::TeamFinish> finish_;           ///< running, after the rounds gave up
    int finish_level_ = -1;                               ///< staircase level finish_ belongs to
    std::chrono::steady_clock::time_point finish_began_;  ///< of finish_
    std::vector<FinishBody> early_finish_;  ///< finish messages heard before finish_ began
    /// Early finish messages kept per robot of the team at most (a peer is a few exchanges ahead
    /// at most: it waits for this robot's); beyond: dropped and counted.
    static constexpr std::size_t kEarlyFinishPerRobot = 8;
    certify::TeamFinishProgress finish_before_;  ///< summed over the finishes ended
    double finish_seconds_before_ = 0.0;         ///< their wall time
    int finishes_ = 0;
    std::string finish_status_;
    std::uint64_t finish_dropped_ = 0;

    std::unique_ptr<DurableLog> log_;
    std::optional<v1::SolverCheckpoint> checkpoint_;  ///< replayed, not restored yet
    /// (steps, report's graph, objective, lambda_min, poses) of the last checkpoint appended
    std::tuple<std::uint64_t, std::uint64_t, double, double, int> checkpoint_key_{};
    bool restored_ = false;  ///< state from the checkpoint; cleared by any change
    std::chrono::steady_clock::time_point restore_checked_{};  ///< changed_ at the last check
    mutable std::mutex snapshot_mutex_;
    SolverSnapshot snapshot_;
    SnapshotKey snapshot_key_{};  ///< KeyOfSnapshot() when snapshot_ was taken
    /// See UpdateSnapshot: how stale an iterating block's snapshot trajectory may be.
    static constexpr std::chrono::milliseconds kTrajectoryPeriod{25};
    std::chrono::steady_clock::time_point trajectory_at_{};  ///< when it was last rounded
    std::uint64_t report_heard_ = 0;                         ///< certificate reports heard
    std::uint64_t snapshot_reports_ = 0;  ///< report_heard_ when the trajectory was rounded
};

}  // namespace certislam::actors
