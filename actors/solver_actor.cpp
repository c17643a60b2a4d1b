// Solver actor: messages in -> SolverState; ticks -> block updates -> public poses out.
#include "actors/solver_actor.h"

#include <algorithm>
#include <cstdio>
#include <random>
#include <stdexcept>

#include "actors/convert.h"
#include "actors/streams.h"
#include "certislam/v1/control.pb.h"

namespace certislam::actors {
void SolverActorConfig::Validate() const {
    solver.Validate();
    if (tick.count() <= 0 || heartbeat.count() <= 0 || bundle_period.count() <= 0 ||
        resend_spacing.count() <= 0) {
        throw std::invalid_argument(
            "SolverActorConfig.tick/heartbeat/bundle_period/resend_spacing: must be > 0");
    }
    if (rounds_stall.count() <= 0) {
        throw std::invalid_argument("SolverActorConfig.rounds_stall = " +
                                    std::to_string(rounds_stall.count()) + " ms: must be > 0");
    }
    if (publish_period.count() < 0) {
        throw std::invalid_argument("SolverActorConfig.publish_period = " +
                                    std::to_string(publish_period.count()) + " ms: must be >= 0");
    }
    if (finish_after_rounds < 0) {
        throw std::invalid_argument("SolverActorConfig.finish_after_rounds = " +
                                    std::to_string(finish_after_rounds) + ": must be >= 0");
    }
    finish.Validate();
}

SolverActor::SolverActor(zmq::context_t& context, const TeamWiring& wiring,
                         const SolverActorConfig& config)
    : NodeActor("solver", context, wiring), config_(config), state_(wiring.robot, config.solver) {
    config_.Validate();
    std::random_device random;
    incarnation_ = (std::uint64_t{random()} << 32 | random()) | 1;
    moving_bundle_wait_ = config_.bundle_period;
}

SolverSnapshot SolverActor::Snapshot() const {
    std::lock_guard lock(snapshot_mutex_);
    return snapshot_;
}

void SolverActor::OnStart() {
    poses_out_ = &OpenServer(Edge::kPoses);
    bundle_out_ = &OpenServer(Edge::kBundle);
    Subscribe();
    if (!config_.log_path.empty()) Replay();
    EveryUntilIdle(config_.tick, std::max<std::chrono::nanoseconds>(config_.tick, kIdleTick),
                   [this] {
                       Tick();
                       return TickDue();
                   });
    Every(config_.heartbeat, [this] { Heartbeat(); });
    UpdateSnapshot();
}

void SolverActor::Subscribe() {
    OpenClient(Edge::kKeyframes, RobotId());
    // Reports and saddle escapes come from the anchor's certifier (the lowest id); the others'
    // streams carry only their rounds' vectors and sums.
    OpenClient(Edge::kCertify, *std::min_element(Wiring().robots.begin(), Wiring().robots.end()));
    for (int r : Wiring().robots) {
        OpenClient(Edge::kLoops, r);
        if (r != RobotId()) OpenClient(Edge::kPoses, r);
    }
    On(v1::Keyframe::descriptor()->full_name(), [this](const transport::Message& m) {
        const auto proto = transport::Unpack<v1::Keyframe>(m);
        const auto pose = proto ? FromProto(proto->t_odom_base()) : std::nullopt;
        const auto id = proto ? FromProto(proto->pose_id()) : std::nullopt;
        if (!pose || !id || id->robot != RobotId()) return false;
        if (state_.AddKeyframe(id->index, *pose)) {
            stamps_ns_.push_back(proto->header().stamp_ns());
            Changed();
        }
        return true;
    });
    On(v1::LoopClosure::descriptor()->full_name(),
       [this](const transport::Message& m) { return OnLoop(m, false); });
    On(v1::Shutdown::descriptor()->full_name(), [this](const transport::Message& m) {
        const auto end = transport::Unpack<v1::Shutdown>(m);
        if (!end) return false;
        if (end->reason() == kEndOfKeyframes && int(end->header().robot_id()) == RobotId()) {
            bundle_dirty_ = bundle_dirty_ || !keyframes_ended_;
            keyframes_ended_ = true;
        }
        // A counted end holds once every loop it counts is in: a late subscriber can hear the
        // repeated marker before the re-sent loops.
        const int from = int(end->header().robot_id());
        if (end->reason() == kEndOfLoops && end->count() <= loops_heard_[from].size() &&
            loops_ended_.insert(from).second) {
            bundle_dirty_ = true;
        }
        return true;
    });
    On(v1::PublicPoses::descriptor()->full_name(),
       [this](const transport::Message& m) { return OnPublicPoses(m); });
    On(v1::FinishMessage::descriptor()->full_name(),
       [this](const transport::Message& m) { return OnFinish(m); });
    On(v1::SolverStatus::descriptor()->full_name(), [this](const transport::Message& m) {
        const auto status = transport::Unpack<v1::SolverStatus>(m);
        if (!status || !IsValidStatus(*status)) return false;
        const bool current = InSession(int(status->header().robot_id()), status->round_session(),
                                       status->incarnation());
        if (status->team_round() > 0) {
            if (config_.synchronous && current) OnRoundSums(*status);
            return true;
        }
        if (status->round_wants_size() > 0 && config_.synchronous && current &&
            !AnswerWants(*status)) {
            return false;
        }
        team_cost_[int(status->header().robot_id())] = status->cost();
        return true;
    });
    On(v1::CertificateReport::descriptor()->full_name(), [this](const transport::Message& m) {
        const auto report = transport::Unpack<v1::CertificateReport>(m);
        if (!report) return false;
        report_ = *report;
        ++report_heard_;
        // S + eta D was PSD, but the bound was too loose for a verdict: the bound is first order
        // in the gradient, so the asynchronous steps go on to the rounds' refined tolerance, and
        // the moved blocks open a new check (the synchronous rounds refine by themselves).
        const double refined =
            std::min(1.0, config_.rounds.refine_rel_grad_tol / config_.solver.rbcd.rel_grad_tol);
        if (report->verdict() == v1::CERTIFICATE_VERDICT_INCONCLUSIVE && report->has_bound() &&
            !refined_ && tolerance_scale_ > refined) {
            tolerance_scale_ = refined;
            refined_ = true;
            refine_steps_left_ = kRefineStepsPerRound * config_.rounds.refine_rounds;
            work_ = true;
        }
        UpdateSnapshot();
        return true;
    });
}

bool SolverActor::NewVerdict(const std::pair<slam::PoseId, slam::PoseId>& ends,
                             std::int64_t version, bool accepted) {
    const auto it = verdicts_.find(ends);
    if (version <= 0) {  // a re-broadcast: adds a loop no matcher verdict spoke of yet
        if (it != verdicts_.end()) return it->second.second && accepted;
        verdicts_[ends] = {0, accepted};
        return true;
    }
    if (it != verdicts_.end() && it->second.first >= version) return false;  // stale
    verdicts_[ends] = {version, accepted};
    return true;
}

void SolverActor::Withdraw(const std::pair<slam::PoseId, slam::PoseId>& ends) {
    if (state_.RemoveLoop(ends.first, ends.second)) Changed();
    if (team_loop_ends_.erase(ends) > 0) {
        std::erase_if(team_loops_, [&](const slam::LoopClosure& l) {
            return l.a == ends.first && l.b == ends.second;
        });
    }
}

bool SolverActor::OnLoop(const transport::Message& m, bool replayed) {
    const auto proto = transport::Unpack<v1::LoopClosure>(m);
    if (!proto) return false;
    const std::int64_t version = proto->header().stamp_ns();  // the matcher's verdict version
    if (const auto ends = WithdrawnEnds(*proto)) {
        if (!NewVerdict(*ends, version, false)) return true;
        Withdraw(*ends);
        if (log_ && !replayed) log_->Append(m);
        return true;
    }
    const auto loop = FromProto(*proto);
    if (!loop) return false;
    if (loop->inter_robot())
        loops_heard_[int(proto->header().robot_id())].insert({loop->a, loop->b});
    if (!NewVerdict({loop->a, loop->b}, version, true)) return true;
    if (state_.AddLoop(*loop)) {
        Changed();
        if (log_ && !replayed) log_->Append(m);
    }
    if (loop->inter_robot() && team_loop_ends_.insert({loop->a, loop->b}).second) {
        team_loops_.push_back(*loop);
    }
    return true;
}

bool SolverActor::OnPublicPoses(const transport::Message& m) {
    const auto proto = transport::Unpack<v1::PublicPoses>(m);
    const auto poses = proto ? FromProto(*proto) : std::nullopt;
    if (!poses || poses->ids.empty()) return false;
    // A peer at our staircase level holds blocks of our rank; other rows are malformed (dropped
    // and counted): they would overrun the neighbour blocks of an RBCD step.
    if (poses->staircase_level == state_.StaircaseLevel() &&
        poses->blocks.rows() != state_.Rank()) {
        return false;
    }
    if (poses->ids.front().robot == RobotId()) {
        // A certifier's saddle escape: our whole block at rank r+1 (RBCD staircase).
        if (poses->staircase_level > state_.StaircaseLevel() &&
            state_.AdoptBlock(poses->blocks, poses->staircase_level)) {
            Changed();
        }
        return true;
    }
    const bool current =
        InSession(poses->ids.front().robot, proto->round_session(), proto->incarnation());
    if (poses->team_round > 0) {  // synchronous rounds (solver_actor_rounds.cpp)
        if (!config_.synchronous || !current) return true;
        if (proto->has_overlap_depth() &&
            proto->overlap_depth() != std::uint32_t(config_.rounds.overlap_depth)) {
            if (!overlap_mismatch_logged_) {  // once: every one is counted as malformed
                overlap_mismatch_logged_ = true;
                std::fprintf(stderr,
                             "solver %d: dropped robot %d's round poses: its "
                             "solver.rounds_overlap is %u, this robot's %d (the team must "
                             "share one)\n",
                             RobotId(), poses->ids.front().robot, proto->overlap_depth(),
                             config_.rounds.overlap_depth);
            }
            return false;
        }
        if (rounds_ && poses->staircase_level == rounds_level_) {
            rounds_->OnPoses(poses->ids.front().robot, poses->team_round - 1, *poses);
            work_ = true;
            AdvanceRounds();
            return true;
        }
        if (poses->staircase_level >= state_.StaircaseLevel()) early_poses_.push_back(*poses);
        work_ = true;
        return true;
    }
    state_.SetNeighbourPoses(*poses);
    work_ = true;
    return true;
}

void SolverActor::Changed() {
    tolerance_scale_ = 1.0;  // a new graph: the configured tolerance again
    overlap_.reset();        // its domain is of the old graph
    boundary_.reset();       // and rounds_' proposable poses are set again (AdvanceRounds)
    refined_ = false;
    if (restored_) report_.reset();  // the checkpoint's report is of the graph before this change
    restored_ = false;
    work_ = true;
    bundle_dirty_ = true;
    moving_bundle_wait_ = config_.bundle_period;  // a new graph's bundle goes out promptly
    changed_ = std::chrono::steady_clock::now();
}

void SolverActor::Tick() {
    TryRestore();
    // A certifier that began reading this robot's bundles (a round named it a neighbour) gets the
    // last one now, not at the next heartbeat's re-send.
    if (bundle_out_->subscribers() != bundle_readers_) {
        const bool more = bundle_out_->subscribers() > bundle_readers_;
        bundle_readers_ = bundle_out_->subscribers();
        bundle_owed_ = bundle_owed_ || more;
    }
    if (bundle_owed_ && local_ok_) SendBundle();
    if (InRounds()) {
        SyncTick();
        return;
    }
    // Public poses at most every publish_period while the graph grows (with a 2 ms tick, sending
    // every step's poses is a large share of a team's bytes); the newest go out late.
    if (publish_pending_ && PublishDue()) {
        Publish();
        UpdateSnapshot();
    }
    if (!work_ || state_.NumPoses() == 0) return;
    double team_cost = 0.0;
    for (const auto& [robot, cost] : team_cost_) team_cost += robot == RobotId() ? 0.0 : cost;
    const certify::SolverStepResult step =
        state_.Step(team_cost + team_cost_[RobotId()], tolerance_scale_);
    ++steps_;
    team_cost_[RobotId()] = step.cost;
    grad_norm_ = step.grad_norm;
    local_ok_ = step.status == certify::SolverStepResult::Status::kLocalOk;
    // Converged against the last poses heard: wait for news instead of spinning.
    work_ = !local_ok_ && step.status != certify::SolverStepResult::Status::kStuck;
    EndRefinementWhenSpent(step);
    // A step that moved the block is published (within publish_period) even when it ends below
    // tolerance: otherwise the team's last refinements travel only with the heartbeat.
    if (!local_ok_ || step.moved) bundle_dirty_ = true;
    if (step.moved) last_move_ = std::chrono::steady_clock::now();
    if (!local_ok_ || step.rebuilt || step.moved) publish_pending_ = true;
    if (publish_pending_ && PublishDue()) Publish();
    if (bundle_dirty_ && BundleDue(std::chrono::steady_clock::now())) SendBundle();
    UpdateSnapshot();
}

// The rounds and the finish move with messages (their handlers act at once); asynchronous steps
// with work_, which messages set; a publish waits for its period. The rest (bundles, a new
// reader, the stall clock) can wait for an idle tick.
bool SolverActor::TickDue() const { return publish_pending_ || (work_ && !InRounds()); }

void SolverActor::EndRefinementWhenSpent(const certify::SolverStepResult& step) {
    if (tolerance_scale_ >= 1.0) return;
    // A gradient that cannot reach the refined tolerance (round-off, stale neighbours) must not
    // keep the robot from ever sending its bundle: like the rounds' refine_rounds, the refinement
    // has a budget, and then the configured tolerance holds again (the certificate re-checks).
    if (--refine_steps_left_ > 0 && step.status != certify::SolverStepResult::Status::kStuck) {
        return;
    }
    tolerance_scale_ = 1.0;
    work_ = true;
}

bool SolverActor::PublishDue() const {
    // Once the graph is final, or has not changed for kGraphSettled (a robot that never ends its
    // streams), every step's poses go out: the team converges on them, and a robot stepping
    // against late poses declares convergence where the team has not.
    const auto now = std::chrono::steady_clock::now();
    return IsFinal() || now - changed_ >= kGraphSettled ||
           now - last_publish_ >= config_.publish_period;
}

void SolverActor::Publish() {
    publish_pending_ = false;
    last_publish_ = std::chrono::steady_clock::now();
    auto poses = ToProto(state_.PublicPoses(steps_));
    *poses.mutable_header() = MakeHeader(RobotId(), NextSequence(), 0);
    StampSession(&poses);
    Send(*poses_out_, transport::Pack(poses), true);
    SendStatus();
}

void SolverActor::SendStatus(const std::vector<certify::RoundWant>& wants) {
    v1::SolverStatus status;
    *status.mutable_header() = MakeHeader(RobotId(), NextSequence(), 0);
    status.set_iteration(steps_);
    status.set_phase(local_ok_ ? v1::SolverStatus::PHASE_CONVERGED
                               : v1::SolverStatus::PHASE_ITERATING);
    status.set_rank_r(static_cast<std::uint32_t>(state_.Rank()));
    status.set_cost(team_cost_[RobotId()]);
    status.set_gradient_norm(grad_norm_);
    status.set_num_poses(static_cast<std::uint32_t>(state_.NumPoses()));
    status.set_staircase_level(static_cast<std::uint32_t>(state_.StaircaseLevel()));
    for (const auto& w : wants) {
        auto* want = status.add_round_wants();
        want->set_robot(static_cast<std::uint32_t>(w.robot));
        want->set_team_round(w.round + 1);
        want->set_sums(w.sums);
    }
    StampSession(&status);
    Send(*poses_out_, transport::Pack(status), true);
}

void SolverActor::Heartbeat() {
    if (state_.NumPoses() == 0) return;
    const bool in_rounds = InRounds() && !rounds_converged_;
    if (in_rounds && finish_) return;  // the finish's messages are never lost (reliable edges)
    if (in_rounds) {
        RequestStalledRound();
        return;
    }
    Publish();
    for (const auto& loop :
         config_.rebroadcast_loops ? state_.InterRobotLoops() : std::vector<slam::LoopClosure>{}) {
        auto proto = ToProto(loop);  // late or restarted peers learn the loops they missed
        *proto.mutable_header() = MakeHeader(RobotId(), NextSequence(), 0);
        Send(*poses_out_, transport::Pack(proto), true);
    }
    if (BundleDue(std::chrono::steady_clock::now())) SendBundle();
    work_ = work_ || !local_ok_;
    UpdateSnapshot();
}

bool SolverActor::BlockAtRest(std::chrono::steady_clock::time_point now) const {
    return now - last_move_ >= config_.bundle_period;
}

bool SolverActor::BundleDue(std::chrono::steady_clock::time_point now) const {
    if (!local_ok_) return false;
    if (!IsFinal()) {  // the mapper's trajectory alone: as often as before the back-off
        return now - last_bundle_ >= (bundle_dirty_ ? config_.bundle_period : kFirstResend);
    }
    if (!bundle_dirty_) return now - last_bundle_ >= unchanged_bundle_wait_;
    return now - last_bundle_ >= (BlockAtRest(now) ? config_.bundle_period : moving_bundle_wait_);
}

void SolverActor::SendBundle() {
    const bool final = IsFinal();
    // The next full bundle of a still moving block, or the next re-send of this one, waits twice
    // as long (BundleDue), never less than bundle_period.
    const auto longest = std::max(config_.bundle_period, kLongestBundleWait);
    if (final && bundle_dirty_) {
        moving_bundle_wait_ = BlockAtRest(std::chrono::steady_clock::now())
                                  ? config_.bundle_period
                                  : std::min(2 * moving_bundle_wait_, longest);
        unchanged_bundle_wait_ = kFirstResend;
    } else if (final) {
        unchanged_bundle_wait_ = std::min(2 * unchanged_bundle_wait_, longest);
    }
    // Status, own edges, then the full block that closes the bundle: only once this robot is
    // final. The certifiers check only when every robot is (CertifierActor::Assemble), so an
    // earlier bundle would be bytes for nothing.
    if (final) {
        v1::SolverStatus status;
        *status.mutable_header() = MakeHeader(RobotId(), NextSequence(), 0);
        status.set_iteration(steps_);
        status.set_phase(v1::SolverStatus::PHASE_CONVERGED);
        status.set_rank_r(static_cast<std::uint32_t>(state_.Rank()));
        status.set_num_poses(static_cast<std::uint32_t>(state_.NumPoses()));
        status.set_gradient_norm(grad_norm_);
        StampSession(&status);  // a new session's result is certified again
        Send(*bundle_out_, transport::Pack(status), false);
        for (const auto& edge : state_.OwnEdges()) {
            auto proto = ToProto(edge);
            *proto.mutable_header() = MakeHeader(RobotId(), NextSequence(), 0);
            Send(*bundle_out_, transport::Pack(proto), false);
        }
        auto block = ToProto(state_.FullBlock(steps_));
        *block.mutable_header() = MakeHeader(RobotId(), NextSequence(), 0);
        Send(*bundle_out_, transport::Pack(block), false);
    }
    // After the bundle: the rounded trajectory for the mapper (the certifier ignores it).
    int anchor = RobotId();
    const auto poses = state_.Trajectory(certify::ComponentAnchor(RobotId(), team_loops_), &anchor);
    const bool certified = report_ && report_->verdict() == v1::CERTIFICATE_VERDICT_CERTIFIED;
    auto trajectory = TrajectoryToProto(RobotId(), poses, certified, steps_);
    *trajectory.mutable_header() = MakeHeader(RobotId(), NextSequence(), 0);
    Send(*bundle_out_, transport::Pack(trajectory), false);
    bundle_dirty_ = false;
    bundle_owed_ = false;
    last_bundle_ = std::chrono::steady_clock::now();
}

SolverActor::SnapshotKey SolverActor::KeyOfSnapshot() const {
    return {steps_, rounds_swept_, round_session_, rounds_converged_, rounds_gave_up_, local_ok_,
            publish_pending_, IsFinal(), state_.StaircaseLevel(), grad_norm_, changed_,
            // Per trust-region step, not per exchange: a snapshot rounds the whole trajectory,
            // and the finish exchanges far more often than it changes (not until it ends).
            finish_ ? std::uint64_t(finish_->Progress().iterations) : 0, round_resends_};
}

void SolverActor::UpdateSnapshot() {
    MaybeCheckpoint();
    snapshot_key_ = KeyOfSnapshot();
    SolverSnapshot s;
    s.num_poses = state_.NumPoses();
    s.final = keyframes_ended_;
    for (int r : Wiring().robots) s.final = s.final && loops_ended_.count(r) > 0;
    s.local_ok = local_ok_ && !publish_pending_;  // converged and the neighbours told so
    s.grad_norm = grad_norm_;
    s.steps = steps_;
    s.rank = state_.Rank();
    s.staircase_level = state_.StaircaseLevel();
    s.inter_robot_loops = static_cast<int>(state_.InterRobotLoops().size());
    // While the block iterates asynchronously its rounded trajectory (an SVD per pose, as costly
    // as a step) is taken at most every kTrajectoryPeriod; at rest, converged, in rounds or with
    // a new certificate report, every time.
    const auto now = std::chrono::steady_clock::now();
    if (!work_ || local_ok_ || InRounds() || report_.has_value() != snapshot_.report.has_value() ||
        report_heard_ != snapshot_reports_ || snapshot_.trajectory.size() != stamps_ns_.size() ||
        now - trajectory_at_ >= kTrajectoryPeriod) {
        trajectory_at_ = now;
        snapshot_reports_ = report_heard_;
        const auto poses =
            state_.Trajectory(certify::ComponentAnchor(RobotId(), team_loops_), &s.anchor);
        for (size_t i = 0; i < poses.size(); ++i) {
            s.trajectory.push_back({static_cast<double>(stamps_ns_[i]) * 1e-9, poses[i]});
        }
    } else {
        s.anchor = snapshot_.anchor;  // only this thread writes snapshot_
        s.trajectory = snapshot_.trajectory;
    }
    s.report = report_;
    s.changed = changed_;
    s.edges = state_.OwnEdges();
    s.team_rounds = rounds_swept_;
    s.round_resends = round_resends_;
    s.restarts = rounds_restarts_ + (rounds_ ? rounds_->Restarts() : 0);
    s.rejected_proposals = rounds_rejected_ + (rounds_ ? rounds_->RejectedProposals() : 0);
    s.overlap_ends = rounds_overlap_ends_ + (rounds_ && rounds_->OverlapEndedAt() ? 1 : 0);
    s.rounds_converged = rounds_converged_;
    s.rounds_gave_up = rounds_gave_up_;
    s.rounds_running = InRounds() && !rounds_converged_;
    s.restored = restored_;
    s.round_session = round_session_;
    s.finish = FinishTotals();
    s.finishes = finishes_;
    s.finish_status = finish_ ? "running" : finish_status_;
    s.finish_dropped = finish_dropped_;
    s.finish_seconds = FinishSeconds();
    std::lock_guard lock(snapshot_mutex_);
    snapshot_ = std::move(s);
}

}  // namespace certislam::actors
