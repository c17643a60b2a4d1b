// Ingest: source -> Keyframe messages, paced, after the local subscribers said hello.
#include "actors/ingest_actor.h"

#include <stdexcept>
#include <string>

#include "actors/convert.h"
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
    : NodeActor("ingest", context, std::move(wiring)),
      source_(std::move(source)),
      config_(std::move(config)) {
    config_.Validate();
}

void IngestActor::OnStart() {
    out_ = &OpenServer(Edge::kKeyframes);
    if (!config_.log_path.empty()) {
        // A restart: what this robot contributed before is published again from the log.
        for (auto& m : ReadDurableLog(config_.log_path).messages) {
            if (m.Is<v1::Keyframe>()) replay_.push_back(std::move(m));
        }
        logged_ = static_cast<int>(replay_.size());
        log_ = std::make_unique<DurableLog>(config_.log_path, config_.log_identity);
    }
    Every(config_.period, [this] { Tick(); });
    Every(config_.end_marker_period, [this] {
        if (finished_) SendEnd();
    });
}

void IngestActor::Tick() {
    if (finished_) return;
    const auto wanted = static_cast<std::size_t>(config_.local_subscribers);
    if (!out_->WaitForSubscribers(wanted, std::chrono::milliseconds(0))) return;
    if (!replay_.empty()) {
        Send(*out_, replay_.front(), false);
        replay_.pop_front();
        ++replayed_;
        ++published_;
        return;
    }
    auto keyframe = source_();
    // A replayable source (simulator, files) starts over: skip what the log already gave.
    while (keyframe && keyframe->index < logged_) keyframe = source_();
    if (!keyframe) {
        finished_ = true;
        SendEnd();
        return;
    }
    keyframe->robot = RobotId();
    const auto message = EncodeKeyframe(*keyframe, NextSequence());
    if (log_) log_->Append(message);
    Send(*out_, message, false);
    ++published_;
}

void IngestActor::SendEnd() {
    v1::Shutdown end;
    *end.mutable_header() = MakeHeader(RobotId(), NextSequence(), 0);
    end.set_reason(kEndOfKeyframes);
    Send(*out_, transport::Pack(end), false);
}

}  // namespace certislam::actors
