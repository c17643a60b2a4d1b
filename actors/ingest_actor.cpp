// Ingest: source -> Keyframe messages, paced, after the local subscribers said hello.
#include "actors/ingest_actor.h"

#include <stdexcept>
#include <string>

#include "actors/codec.h"
#include "certislam/v1/control.pb.h"

namespace certislam::actors {

void IngestConfig::Validate() const {
    if (local_subscribers < 0) {
        throw std::invalid_argument("IngestConfig.local_subscribers = " +
                                    std::to_string(local_subscribers) + ": must be >= 0");
    }
    if (period.count() <= 0 || end_marker_period.count() <= 0) {
        throw std::invalid_argument("IngestConfig.period/end_marker_period: must be > 0 ms");
    }
}

IngestActor::IngestActor(zmq::context_t& context, TeamWiring wiring, KeyframeSource source,
                         IngestConfig config)
    : NodeActor("ingest", context, std::move(wiring)), source_(std::move(source)), config_(config) {
    config_.Validate();
}

void IngestActor::OnStart() {
    out_ = &OpenServer(Edge::kKeyframes);
    Every(config_.period, [this] { Tick(); });
    Every(config_.end_marker_period, [this] {
        if (finished_) SendEnd();
    });
}

void IngestActor::Tick() {
    if (finished_) return;
    const auto wanted = static_cast<std::size_t>(config_.local_subscribers);
    if (!out_->WaitForSubscribers(wanted, std::chrono::milliseconds(0))) return;
    auto keyframe = source_();
    if (!keyframe) {
        finished_ = true;
        SendEnd();
        return;
    }
    keyframe->robot = RobotId();
    Send(*out_, EncodeKeyframe(*keyframe, NextSequence()), false);
    ++published_;
}

void IngestActor::SendEnd() {
    v1::Shutdown end;
    *end.mutable_header() = MakeHeader(RobotId(), NextSequence(), 0);
    end.set_reason(kEndOfKeyframes);
    Send(*out_, transport::Pack(end), false);
}

}  // namespace certislam::actors
