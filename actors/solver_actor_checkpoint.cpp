// Solver actor: the durable log's replay, and the checkpoint of a certified state. A robot that
// restarts after its team certified and left replays the same graph but has no peer to solve or
// certify with; the checkpoint gives it back the certified X with the report proven at it. A
// bound holds only for the graph and X it was proven at, so a checkpoint is restored only when
// the replayed graph has its digest, and the X restored is the one the certifier checked.
#include <cstdio>
#include <tuple>

#include "actors/certifier_bundles.h"
#include "actors/convert.h"
#include "actors/solver_actor.h"

namespace certislam::actors {
namespace {

/// Every edge at the robot's poses: its own edges and the inter-robot loops whose tail is a peer's.
std::uint64_t GraphAtOwnPoses(const certify::SolverState& state) {
    std::vector<slam::LoopClosure> edges = state.OwnEdges();
    const auto loops = state.InterRobotLoops();
    edges.insert(edges.end(), loops.begin(), loops.end());
    return EdgesDigest(std::move(edges));
}

}  // namespace

void SolverActor::Replay() {
    // Loops accepted before a restart (some found by peers that will not send them again), and
    // the last checkpoint, restored once the keyframes are replayed too (TryRestore).
    for (const auto& m : ReadDurableLog(config_.log_path).messages) {
        if (auto c = transport::Unpack<v1::SolverCheckpoint>(m)) {
            checkpoint_ = std::move(*c);
            continue;
        }
        OnLoop(m, true);
    }
    log_ = std::make_unique<DurableLog>(config_.log_path, config_.log_identity);
}

// Called with every snapshot: the state a snapshot shows as certified (the robot's output when it
// ends) is in the log before any caller can see it.
void SolverActor::MaybeCheckpoint() {
    if (!log_ || restored_ || !report_ || !IsFinal() || !local_ok_ ||
        report_->verdict() != v1::CERTIFICATE_VERDICT_CERTIFIED) {
        return;
    }
    const auto key = std::make_tuple(steps_, report_->iteration(), report_->objective(),
                                     report_->lambda_min(), state_.NumPoses());
    if (key == checkpoint_key_) return;  // nothing new since the last one appended
    checkpoint_key_ = key;
    v1::SolverCheckpoint c;
    *c.mutable_header() = MakeHeader(RobotId(), NextSequence(), 0);
    *c.mutable_report() = *report_;
    *c.mutable_own() = ToProto(state_.FullBlock(steps_));
    *c.mutable_neighbours() = ToProto(state_.NeighbourBlocks());
    for (int r : loops_ended_) c.add_loops_ended(static_cast<std::uint32_t>(r));
    for (const auto& loop : team_loops_) *c.add_team_loops() = ToProto(loop);
    c.set_graph_digest(GraphAtOwnPoses(state_));
    log_->Append(transport::Pack(c));
}

// Waits, after the replayed keyframes, until the graph is the checkpoint's (loops its own
// matcher finds again come late); a graph that never gets there is solved with the team as usual.
void SolverActor::TryRestore() {
    if (!checkpoint_ || !keyframes_ended_ || changed_ == restore_checked_) return;
    restore_checked_ = changed_;  // the digest is rechecked only after a change
    const v1::SolverCheckpoint& c = *checkpoint_;
    if (GraphAtOwnPoses(state_) != c.graph_digest()) return;
    const auto own = FromProto(c.own());
    const auto neighbours = c.neighbours().pose_ids_size() > 0
                                ? FromProto(c.neighbours())
                                : std::optional(certify::PoseBlocks{});
    if (!own || !neighbours || own->ids.size() != size_t(state_.NumPoses()) ||
        c.report().verdict() != v1::CERTIFICATE_VERDICT_CERTIFIED ||
        !state_.AdoptBlock(own->blocks, own->staircase_level)) {
        std::fprintf(stderr, "solver %d: the durable log's checkpoint is malformed: not restored\n",
                     RobotId());
        checkpoint_.reset();
        return;
    }
    state_.SetNeighbourPoses(*neighbours);
    for (const std::uint32_t r : c.loops_ended()) loops_ended_.insert(static_cast<int>(r));
    for (const auto& proto : c.team_loops()) {
        const auto loop = FromProto(proto);
        if (loop && team_loop_ends_.insert({loop->a, loop->b}).second) team_loops_.push_back(*loop);
    }
    report_ = c.report();
    checkpoint_.reset();
    restored_ = true;
    local_ok_ = true;
    work_ = false;
    bundle_dirty_ = true;
    publish_pending_ = true;
    UpdateSnapshot();
}

}  // namespace certislam::actors
