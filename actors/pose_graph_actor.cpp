// Pose-graph source: a robot's block of a pose graph -> keyframe and loop streams.
#include "actors/pose_graph_actor.h"

#include <chrono>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>

#include "actors/convert.h"
#include "actors/streams.h"
#include "certislam/v1/control.pb.h"

namespace certislam::actors {
namespace {

constexpr std::chrono::milliseconds kPollPeriod{5};   ///< subscriber check
constexpr std::chrono::milliseconds kIdlePoll{100};   ///< ... once block and edges went out
constexpr std::chrono::milliseconds kEndPeriod{500};  ///< end markers repeated
/// Version of every edge (a matcher's verdict version): one, as a file's edges never change.
constexpr std::int64_t kEdgeVersion = 1;

}  // namespace

PoseGraphActor::PoseGraphActor(zmq::context_t& context, TeamWiring wiring, slam::RobotGraph graph)
    : NodeActor("pose_graph", context, std::move(wiring)), graph_(std::move(graph)) {
    if (graph_.robot != RobotId()) {
        throw std::invalid_argument("PoseGraphActor: block of robot " +
                                    std::to_string(graph_.robot) + " given to robot " +
                                    std::to_string(RobotId()));
    }
    std::set<std::pair<slam::PoseId, slam::PoseId>> ends;
    for (const auto& edge : graph_.inter) ends.insert({edge.a, edge.b});
    inter_ends_ = ends.size();
}

void PoseGraphActor::OnStart() {
    keyframes_out_ = &OpenServer(Edge::kKeyframes);
    loops_out_ = &OpenServer(Edge::kLoops);
    // Once sent, only a restarted reader needs them again: checked less often.
    EveryUntilIdle(kPollPeriod, kIdlePoll, [this] {
        // The local solver reads the keyframe stream; every robot's solver the loop stream.
        const std::size_t local = keyframes_out_->subscribers();
        if (local >= 1 && local > keyframe_subscribers_) {
            keyframe_subscribers_ = local;
            SendBlock();
        }
        const std::size_t team = loops_out_->subscribers();
        if (team >= Wiring().robots.size() && team > loop_subscribers_) {
            loop_subscribers_ = team;
            SendInterRobotEdges();
        }
        finished_ = block_sent_ && edges_sent_;
        return !finished_;
    });
    Every(kEndPeriod, [this] { SendEnds(); });
}

void PoseGraphActor::SendBlock() {
    for (size_t k = 0; k < graph_.initial.size(); ++k) {
        slam::Keyframe keyframe;
        keyframe.robot = RobotId();
        keyframe.index = static_cast<int>(k);
        keyframe.stamp_ns = static_cast<std::int64_t>(k);  // the pose index: a file has no time
        keyframe.T_odom_sensor = graph_.initial[k];
        Send(*keyframes_out_, EncodeKeyframe(keyframe, NextSequence()), false);
    }
    for (const auto& edge : graph_.intra) {
        auto proto = ToProto(edge);
        *proto.mutable_header() = MakeHeader(RobotId(), NextSequence(), kEdgeVersion);
        Send(*keyframes_out_, transport::Pack(proto), false);
    }
    block_sent_ = true;
    SendEnds();
}

void PoseGraphActor::SendInterRobotEdges() {
    for (const auto& edge : graph_.inter) {
        auto proto = ToProto(edge);
        *proto.mutable_header() = MakeHeader(RobotId(), NextSequence(), kEdgeVersion);
        Send(*loops_out_, transport::Pack(proto), true);
    }
    edges_sent_ = true;
    SendEnds();
}

void PoseGraphActor::SendEnds() {
    if (block_sent_) {
        v1::Shutdown end;
        *end.mutable_header() = MakeHeader(RobotId(), NextSequence(), 0);
        end.set_reason(kEndOfKeyframes);
        Send(*keyframes_out_, transport::Pack(end), false);
    }
    if (edges_sent_) {
        v1::Shutdown end;
        *end.mutable_header() = MakeHeader(RobotId(), NextSequence(), 0);
        end.set_reason(kEndOfLoops);
        end.set_count(inter_ends_);  // a solver holding fewer waits for the re-sent ones
        Send(*loops_out_, transport::Pack(end), true);
    }
}

}  // namespace certislam::actors
