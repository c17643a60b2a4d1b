// Accepted inter-robot loops of this robot, from the matchers' loop streams.
#include "actors/ros/loop_watcher.h"

#include "actors/convert.h"
#include "actors/loop_matcher_actor.h"

namespace certislam::actors {

LoopWatcherActor::LoopWatcherActor(zmq::context_t& context, TeamWiring wiring)
    : NodeActor("loop_watcher", context, std::move(wiring)) {}

void LoopWatcherActor::OnStart() {
    for (const int r : Wiring().robots) OpenClient(Edge::kLoops, r);
    On(v1::LoopClosure::descriptor()->full_name(),
       [this](const transport::Message& m) { return OnLoop(m); });
}

bool LoopWatcherActor::OnLoop(const transport::Message& m) {
    const auto proto = transport::Unpack<v1::LoopClosure>(m);
    if (!proto) return false;
    const auto version = static_cast<std::int64_t>(proto->header().stamp_ns());
    Verdict verdict;
    verdict.version = version;
    std::pair<slam::PoseId, slam::PoseId> ends;
    if (const auto withdrawn = WithdrawnEnds(*proto)) {
        ends = *withdrawn;
    } else {
        const auto loop = FromProto(*proto);
        if (!loop) return false;
        ends = {loop->a, loop->b};
        verdict.loop = *loop;
    }
    if (ends.first.robot == ends.second.robot) return true;
    if (ends.first.robot != RobotId() && ends.second.robot != RobotId()) return true;
    std::lock_guard lock(mutex_);
    const auto it = loops_.find(ends);
    // A re-broadcast (version 0) never overrides a verdict already heard.
    if (it != loops_.end() && (version == 0 || version < it->second.version)) return true;
    loops_[ends] = std::move(verdict);
    return true;
}

std::vector<slam::LoopClosure> LoopWatcherActor::Loops() const {
    std::lock_guard lock(mutex_);
    std::vector<slam::LoopClosure> out;
    for (const auto& [ends, verdict] : loops_) {
        if (verdict.loop) out.push_back(*verdict.loop);
    }
    return out;
}

}  // namespace certislam::actors
