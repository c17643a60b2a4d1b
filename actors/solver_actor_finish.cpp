// Solver actor, synchronous mode: the team's second-order finish (certify/pipeline/team_finish.h)
// after rounds too slow to converge (solver.finish_after_rounds, solver.rounds_max), driven by the
// peers' finish messages on the poses stream.
#include <algorithm>
#include <cstdio>

#include "actors/convert.h"
#include "actors/solver_actor.h"

namespace certislam::actors {
namespace {

const char* StatusName(certify::TeamFinish::Status s) {
    switch (s) {
        case certify::TeamFinish::Status::kRunning:
            return "running";
        case certify::TeamFinish::Status::kConverged:
            return "converged";
        case certify::TeamFinish::Status::kNotConverged:
            return "not converged";
        case certify::TeamFinish::Status::kInconsistent:
            return "inconsistent";
    }
    return "";
}

void Add(const certify::TeamFinishProgress& p, certify::TeamFinishProgress* sum) {
    sum->iterations += p.iterations;
    sum->accepted += p.accepted;
    sum->tcg_iterations += p.tcg_iterations;
    sum->exchanges += p.exchanges;
    sum->reductions += p.reductions;
    sum->entries_sent += p.entries_sent;
    sum->dropped += p.dropped;
    sum->cost = p.cost;
    sum->grad_norm = p.grad_norm;
    sum->at_floor = p.at_floor;
}

}  // namespace

// Every robot's rounds give up at the same round (they decide from the same sums), so every
// robot starts its finish from the same X: its own block of that round.
void SolverActor::StartFinish() {
    finish_.emplace(RobotId(), Wiring().robots, state_.FullBlock(steps_).blocks,
                    certify::EdgesTouching(state_), config_.finish);
    finish_level_ = state_.StaircaseLevel();
    finish_began_ = std::chrono::steady_clock::now();
    finish_status_ = StatusName(finish_->status());
    std::fprintf(stderr, "solver %d: the rounds hand over to the team's finish after %llu\n",
                 RobotId(), static_cast<unsigned long long>(rounds_swept_));
    finish_->Start();
    const auto early = std::move(early_finish_);
    early_finish_.clear();
    for (const auto& body : early) {
        if (body.staircase_level == finish_level_) FeedFinish(body);
    }
    PumpFinish();
}

bool SolverActor::OnFinish(const transport::Message& m) {
    const auto proto = transport::Unpack<v1::FinishMessage>(m);
    const auto body = proto ? FromProto(*proto) : std::nullopt;
    if (!body) return false;
    const auto& team = Wiring().robots;
    if (!config_.synchronous || body->robot == RobotId() ||
        std::find(team.begin(), team.end(), body->robot) == team.end()) {
        ++finish_dropped_;
        return true;
    }
    if (!InSession(body->robot, proto->round_session(), proto->incarnation())) return true;
    // Edges and vectors go to their receiver's robot topic only; one for another robot (a peer
    // that subscribed to a topic not its own) is not this one's to read.
    if (body->kind != v1::FinishMessage::KIND_SUMS && body->to != RobotId()) return true;
    if (finish_ && body->staircase_level == finish_level_) {
        FeedFinish(*body);
        PumpFinish();
    } else if (!finish_ && body->staircase_level >= state_.StaircaseLevel() &&
               early_finish_.size() < kEarlyFinishPerRobot * team.size()) {
        early_finish_.push_back(*body);
    } else {
        ++finish_dropped_;  // of an older level, or more than a peer a few exchanges ahead sends
    }
    return true;
}

void SolverActor::FeedFinish(const FinishBody& body) {
    switch (body.kind) {
        case v1::FinishMessage::KIND_EDGES:
            finish_->OnEdges(body.robot, body.ids, body.edges);
            return;
        case v1::FinishMessage::KIND_VECTOR:
            finish_->OnVector(body.robot, body.step, body.ids, body.blocks);
            return;
        case v1::FinishMessage::KIND_SUMS:
            finish_->OnSums(body.robot, body.step, body.values);
            return;
        default:
            return;
    }
}

void SolverActor::PumpFinish() {
    // Edges and vectors go to their one neighbour (the poses stream's robot topic), sums to all.
    const auto send = [this](v1::FinishMessage proto) {
        *proto.mutable_header() = MakeHeader(RobotId(), NextSequence(), 0);
        proto.set_staircase_level(static_cast<std::uint32_t>(finish_level_));
        StampSession(&proto);
        if (proto.kind() == v1::FinishMessage::KIND_SUMS) {
            Send(*poses_out_, transport::Pack(proto), true);
        } else {
            SendToRobot(*poses_out_, int(proto.to_robot()), transport::Pack(proto), true);
        }
    };
    for (bool moved = true; moved && finish_;) {
        moved = false;
        for (const auto& e : finish_->TakeEdges()) {
            send(ToProto(e));
            moved = true;
        }
        for (const auto& v : finish_->TakeVectors()) {
            send(ToProto(v));
            moved = true;
        }
        for (const auto& s : finish_->TakeSums()) {
            send(ToProto(s));
            finish_->OnSums(RobotId(), s.step, s.values);  // the own share, as every robot's
            moved = true;
        }
        if (moved) last_round_progress_ = std::chrono::steady_clock::now();
        if (finish_->Done()) EndFinish();
    }
    if (finish_) RefreshFinishCounters();
}

// Between two snapshots (one per trust-region step) the finish's counters still move: a run read
// mid-finish, at a timeout, reports them as they are, not a step old.
void SolverActor::RefreshFinishCounters() {
    const auto totals = FinishTotals();
    const double seconds = FinishSeconds();
    std::lock_guard lock(snapshot_mutex_);
    snapshot_.finish = totals;
    snapshot_.finish_seconds = seconds;
}

// Converged: the finish's X is the rounds' result (certified as theirs would be). Otherwise the
// robots go on asynchronously from it, as after max_rounds; every robot ends at the same sum.
void SolverActor::EndFinish() {
    const auto status = finish_->status();
    finish_status_ = StatusName(status);
    const auto& p = finish_->Progress();
    const double seconds = FinishSeconds() - finish_seconds_before_;
    finish_seconds_before_ += seconds;
    std::fprintf(stderr,
                 "solver %d: the team's finish %s: %d trust-region steps, %d CG in %.2f s\n",
                 RobotId(), finish_status_.c_str(), p.iterations, p.tcg_iterations, seconds);
    Add(finish_->Progress(), &finish_before_);
    ++finishes_;
    state_.SetNeighbourPoses(finish_->NeighbourPoses());
    state_.SetOwnBlock(finish_->Block());
    finish_.reset();
    early_finish_.clear();  // of this finish: a new one needs a new session or level
    ++steps_;
    grad_norm_ = state_.Evaluate().grad_norm;
    overlap_.reset();
    bundle_dirty_ = true;
    publish_pending_ = true;
    work_ = true;
    if (status == certify::TeamFinish::Status::kConverged) {
        rounds_converged_ = true;
        local_ok_ = true;
    } else {
        std::fprintf(stderr, "solver %d: asynchronous updates from the finish's X\n", RobotId());
        rounds_gave_up_ = true;
        local_ok_ = false;
    }
    UpdateSnapshot();
}

void SolverActor::DropFinish() {
    if (!finish_) return;  // a saddle escape or a new session: the finish's X is of the old one
    finish_seconds_before_ = FinishSeconds();
    Add(finish_->Progress(), &finish_before_);
    finish_.reset();
    finish_status_ = "dropped";
}

double SolverActor::FinishSeconds() const {
    if (!finish_) return finish_seconds_before_;
    return finish_seconds_before_ +
           std::chrono::duration<double>(std::chrono::steady_clock::now() - finish_began_).count();
}

certify::TeamFinishProgress SolverActor::FinishTotals() const {
    certify::TeamFinishProgress out = finish_before_;
    if (finish_) Add(finish_->Progress(), &out);
    return out;
}

}  // namespace certislam::actors
