// Solver actor, synchronous mode: RBCD++ rounds (certify/pipeline/team_rounds.h) driven by the
// round-tagged public poses and sums of the other robots' solvers.
#include <algorithm>
#include <cstdio>
#include <string>

#include "actors/convert.h"
#include "actors/solver_actor.h"
#include "actors/streams.h"

namespace certislam::actors {
namespace {

/// Keeps a round's message and the one before it: a robot can be one round behind its peers (it
/// decides a round only with every robot's sums of it), so a message it lost in the round before
/// the sender's last is still needed, and the sender re-sends only what it keeps.
template <typename K, typename T>
void KeepLastTwo(std::vector<K>* kept, T message) {
    kept->push_back(K{std::move(message), std::chrono::steady_clock::now(), {}});
    if (kept->size() > 2) kept->erase(kept->begin());
}

}  // namespace

bool SolverActor::IsFinal() const {
    bool final = keyframes_ended_;
    for (int r : Wiring().robots) final = final && loops_ended_.count(r) > 0;
    return final;
}

bool SolverActor::InRounds() const {
    return config_.synchronous && !rounds_gave_up_ && (!config_.async_until_final || IsFinal());
}

void SolverActor::SendRoundPoses(std::uint64_t round) {
    certify::PoseBlocks poses =
        certify::RoundPoses(state_, Boundary(), round, steps_, overlap_ ? &*overlap_ : nullptr);
    poses.team_round = round + 1;
    poses.sweep_color = rounds_->SweepColor();
    auto proto = ToProto(poses);
    *proto.mutable_header() = MakeHeader(RobotId(), NextSequence(), 0);
    proto.set_overlap_depth(static_cast<std::uint32_t>(config_.rounds.overlap_depth));
    StampSession(&proto);
    SendToNeighbours(proto);
    KeepLastTwo(&last_round_poses_, std::move(proto));
}

// Only the neighbours' rounds read a robot's round poses (TeamRounds::OnPoses drops the
// others'): sent to them alone, no other solver of the team decodes them.
void SolverActor::SendToNeighbours(const v1::PublicPoses& poses) {
    if (!rounds_) return;
    const auto message = transport::Pack(poses);
    for (int j : rounds_->Neighbours()) SendToRobot(*poses_out_, j, message, true);
}

void SolverActor::SendRoundSums(std::uint64_t round, double cost, double grad_norm) {
    v1::SolverStatus status;
    *status.mutable_header() = MakeHeader(RobotId(), NextSequence(), 0);
    status.set_iteration(steps_);
    status.set_phase(v1::SolverStatus::PHASE_ITERATING);
    status.set_rank_r(static_cast<std::uint32_t>(state_.Rank()));
    status.set_cost(cost);
    status.set_gradient_norm(grad_norm);
    status.set_num_poses(static_cast<std::uint32_t>(state_.NumPoses()));
    status.set_team_round(round + 1);
    status.set_staircase_level(static_cast<std::uint32_t>(state_.StaircaseLevel()));
    StampSession(&status);
    Send(*poses_out_, transport::Pack(status), true);
    KeepLastTwo(&last_round_sums_, std::move(status));
}

// Rounds stalled for a heartbeat: a peer may have joined late or a message may be lost. The
// status names what this robot's rounds wait for, and its senders re-send only that, to it alone
// (AnswerWants): a pushed re-send of every kept round to every neighbour would mostly repeat
// what they have. At a doubling interval up to kMaxResendWait while no round progresses (a round
// waits for its colours one after another). The status also tells the peers this solver's
// session and incarnation.
void SolverActor::RequestStalledRound() {
    const auto now = std::chrono::steady_clock::now();
    if (now - last_round_progress_ < config_.heartbeat || now - last_resend_ < resend_wait_) return;
    last_resend_ = now;
    resend_wait_ = std::min(2 * resend_wait_, std::max(config_.heartbeat, kMaxResendWait));
    // The wants are of the rounds' level; after a saddle escape, until SyncTick drops those
    // rounds, the status carries none (it is stamped with the new level).
    SendStatus(rounds_ && rounds_level_ == state_.StaircaseLevel()
                   ? rounds_->Wants()
                   : std::vector<certify::RoundWant>{});
}

bool SolverActor::AnswerWants(const v1::SolverStatus& request) {
    const auto& team = Wiring().robots;
    const int from = int(request.header().robot_id());
    // A round waits for one message of each robot at most.
    if (std::size_t(request.round_wants_size()) > team.size()) return false;
    if (from == RobotId() || std::find(team.begin(), team.end(), from) == team.end()) return true;
    const auto level = request.staircase_level();
    const auto now = std::chrono::steady_clock::now();
    const auto answer = [&](auto* kept, const v1::RoundWant& want) {
        for (auto& k : *kept) {
            if (k.message.team_round() == want.team_round() &&
                k.message.staircase_level() == level && SendAgain(&k, from, now)) {
                ++round_resends_;
            }
        }
    };
    for (const auto& want : request.round_wants()) {
        if (want.robot() != std::uint32_t(RobotId())) continue;
        if (want.sums()) {
            answer(&last_round_sums_, want);
        } else if (rounds_ && rounds_->Neighbours().count(from) > 0) {  // nobody else reads them
            answer(&last_round_poses_, want);
        }
    }
    return true;
}

template <typename T>
bool SolverActor::SendAgain(Kept<T>* kept, int peer, std::chrono::steady_clock::time_point now) {
    auto& [next, wait] =
        kept->again.try_emplace(peer, kept->sent + config_.resend_spacing, config_.resend_spacing)
            .first->second;
    if (now < next) return false;
    if (!SendToRobot(*poses_out_, peer, transport::Pack(kept->message), true)) return false;
    wait = std::min(2 * wait, std::max(config_.resend_spacing, kMaxResendWait));
    next = now + wait;
    return true;
}

void SolverActor::OnRoundSums(const v1::SolverStatus& status) {
    if (!rounds_ || int(status.staircase_level()) != rounds_level_) {
        if (int(status.staircase_level()) >= state_.StaircaseLevel()) early_sums_.push_back(status);
        return;
    }
    rounds_->OnSums(int(status.header().robot_id()), status.team_round() - 1, status.cost(),
                    status.gradient_norm());
    work_ = true;
    AdvanceRounds();
}

// A known peer with a new incarnation restarted and lost its rounds: its old session can never
// converge with it, so this robot opens the next session; a higher session heard is joined. Every
// robot ends in the highest session, whose rounds start again from the robots' iterates.
bool SolverActor::InSession(int robot, std::uint64_t session, std::uint64_t incarnation) {
    const auto& team = Wiring().robots;
    if (!config_.synchronous || robot == RobotId() ||
        std::find(team.begin(), team.end(), robot) == team.end()) {
        return true;
    }
    std::uint64_t& known = incarnations_[robot];
    const bool restarted = known != 0 && incarnation != 0 && incarnation != known;
    if (incarnation != 0) known = incarnation;
    if (restarted) {
        const std::uint64_t next = std::max(session, round_session_) + 1;
        std::fprintf(stderr, "solver %d: robot %d restarted: round session %llu\n", RobotId(),
                     robot, static_cast<unsigned long long>(next));
        NewSession(next);
    } else if (session > round_session_) {
        NewSession(session);
    }
    return session == round_session_;
}

// Rejoins: the rounds of the old session (converged, stalled or given up) are dropped and begin
// again from the current iterate (not the chordal start), and their result is certified again.
void SolverActor::NewSession(std::uint64_t session) {
    round_session_ = session;
    early_poses_.clear();  // of older sessions
    early_sums_.clear();
    early_finish_.clear();
    last_round_poses_.clear();
    last_round_sums_.clear();
    last_round_progress_ = std::chrono::steady_clock::now();
    resend_wait_ = config_.heartbeat;
    if (!rounds_ && !restored_ && !rounds_gave_up_) return;  // no rounds begun yet
    DropRounds();
    chordal_started_ = true;  // a restored block is kept too
    rounds_converged_ = false;
    rounds_gave_up_ = false;
    restored_ = false;
    report_.reset();  // of the iterate this robot leaves
    local_ok_ = false;
    work_ = true;
    bundle_dirty_ = true;
}

// Performs one action of the rounds; false when the robot has to wait for messages.
bool SolverActor::SyncAction(const certify::RoundAction& a) {
    using K = certify::RoundAction::Kind;
    switch (a.kind) {
        case K::kWait:
            return false;
        case K::kAlign:
            state_.SetNeighbourPoses(a.neighbours);
            state_.AlignToLowerNeighbour();
            rounds_->SweepDone(0, state_.FullBlock(steps_).blocks);
            SendRoundPoses(0);
            return true;
        case K::kSweep: {
            state_.SetNeighbourPoses(a.neighbours);
            grad_norm_ = certify::SweepRound(a, config_.rounds.overlap_depth, config_.solver.rbcd,
                                             *rounds_, &state_, &overlap_);
            ++steps_;
            ++rounds_swept_;
            rounds_->SweepDone(a.round, state_.FullBlock(steps_).blocks);
            SendRoundPoses(a.round);
            return true;
        }
        case K::kEvaluate: {
            state_.SetNeighbourPoses(a.neighbours);
            const auto eval = state_.Evaluate();
            rounds_->OnSums(RobotId(), a.round, eval.cost, eval.grad_norm);
            team_cost_[RobotId()] = eval.cost;
            SendRoundSums(a.round, eval.cost, eval.grad_norm);
            return true;
        }
        case K::kConverged:
            state_.SetNeighbourPoses(a.neighbours);
            state_.SetOwnBlock(a.own_start);
            grad_norm_ = state_.Evaluate().grad_norm;
            overlap_.reset();  // no sweep follows: its block solver frees before the certificate
            rounds_converged_ = true;
            local_ok_ = true;
            bundle_dirty_ = true;
            publish_pending_ = true;
            return false;
        case K::kGaveUp:
            if (FinishesRounds()) {
                StartFinish();  // too slow to converge in max_rounds, or they did not
            } else {
                rounds_gave_up_ = true;
            }
            return false;
    }
    return false;
}

// Takes every action the rounds allow now. Called when a round message arrives, not only on the
// tick: each round is several message hops, and waiting for a tick at every hop paced the team.
void SolverActor::AdvanceRounds() {
    if (!rounds_ || finish_ || rounds_level_ != state_.StaircaseLevel()) return;
    if (!boundary_) rounds_->SetProposable(Boundary().proposable);  // the graph changed
    bool progressed = false;
    while (!rounds_converged_ && !rounds_gave_up_ && SyncAction(rounds_->Next())) {
        progressed = true;
    }
    if (!proposals_logged_ && rounds_->RejectedProposals() > 0) {
        proposals_logged_ = true;  // once: every one is counted (rejected_proposals)
        std::fprintf(stderr,
                     "solver %d: dropped a neighbour's proposal of a pose outside its "
                     "reach or not a pose\n",
                     RobotId());
    }
    if (progressed) {
        last_round_progress_ = std::chrono::steady_clock::now();
        resend_wait_ = config_.heartbeat;
    }
}

// Synchronous mode: nothing before the graph is final; then rounds until converged (or given up:
// asynchronous steps from there, Tick's usual path).
void SolverActor::SyncTick() {
    if (!IsFinal() || state_.NumPoses() == 0) return;
    if (restored_) {  // the certified rounds' result came from the log: no peer to sweep with
        if (publish_pending_) Publish();
        if (bundle_dirty_) SendBundle();
        if (KeyOfSnapshot() != snapshot_key_) UpdateSnapshot();
        return;
    }
    if (rounds_ && rounds_level_ != state_.StaircaseLevel()) {
        DropRounds();  // a saddle escape: new rounds from the adopted block
        rounds_converged_ = false;
        local_ok_ = false;
    }
    if (!rounds_) StartRounds();
    AdvanceRounds();
    const auto now = std::chrono::steady_clock::now();
    if (!rounds_converged_ && !rounds_gave_up_ && now - last_round_progress_ >= RoundsStall()) {
        const std::string waiting = rounds_ ? rounds_->Waiting() : std::string();
        std::fprintf(stderr, "solver %d: round session %llu stalled (%s): asynchronous updates\n",
                     RobotId(), static_cast<unsigned long long>(round_session_),
                     waiting.empty() ? "no round message awaited" : waiting.c_str());
        DropFinish();            // a finish waiting for a silent peer too
        rounds_gave_up_ = true;  // Tick's asynchronous path from here, as after max_rounds
        work_ = true;
        return;
    }
    work_ = false;
    if (publish_pending_) Publish();
    if (local_ok_ && bundle_dirty_ && now - last_bundle_ >= config_.bundle_period) SendBundle();
    // A snapshot copies the trajectory and the edges: not on every tick of a converged team.
    if (KeyOfSnapshot() != snapshot_key_) UpdateSnapshot();
}

void SolverActor::StartRounds() {
    const auto nbrs = state_.Neighbours();
    certify::TeamRoundsConfig rounds = config_.rounds;
    rounds.hand_over_after = config_.finish_after_rounds;
    rounds_.emplace(RobotId(), Wiring().robots, std::set<int>(nbrs.begin(), nbrs.end()), rounds);
    rounds_->SetProposable(Boundary().proposable);
    overlap_.reset();
    rounds_level_ = state_.StaircaseLevel();
    local_ok_ = false;  // an asynchronous phase's convergence says nothing of the rounds
    if (rounds_level_ == 0 && !chordal_started_) state_.LocalChordalStart();
    chordal_started_ = true;
    for (const auto& p : early_poses_) {
        if (p.staircase_level == rounds_level_ && !p.ids.empty() &&
            p.blocks.rows() == state_.Rank()) {
            rounds_->OnPoses(p.ids.front().robot, p.team_round - 1, p);
        }
    }
    early_poses_.clear();
    const auto sums = std::move(early_sums_);
    early_sums_.clear();
    for (const auto& s : sums) OnRoundSums(s);
    last_round_progress_ = std::chrono::steady_clock::now();
    resend_wait_ = config_.heartbeat;
}

void SolverActor::DropRounds() {
    if (rounds_) {
        rounds_restarts_ += rounds_->Restarts();
        rounds_rejected_ += rounds_->RejectedProposals();
        if (rounds_->OverlapEndedAt()) ++rounds_overlap_ends_;
    }
    rounds_.reset();
    overlap_.reset();
    DropFinish();
}

// Round 0 places the robots one after another in id order (TeamRounds, kAlign): the last of N
// waits for N - 1 placements before it moves, each a message hop through a loaded host.
std::chrono::milliseconds SolverActor::RoundsStall() const {
    return config_.rounds_stall +
           kStallPerRobot * static_cast<std::int64_t>(Wiring().robots.size());
}

bool SolverActor::FinishesRounds() const { return config_.finish_after_rounds > 0; }

const certify::RoundBoundary& SolverActor::Boundary() {
    if (!boundary_) boundary_ = certify::BoundaryOf(state_, config_.rounds.overlap_depth);
    return *boundary_;
}

}  // namespace certislam::actors
