// Descriptor: Keyframe in, Scan Context out (to own and peers' loop matchers).
#include "actors/descriptor_actor.h"

#include "actors/convert.h"
#include "actors/convert_descriptor.h"
#include "actors/streams.h"
#include "certislam/v1/control.pb.h"

namespace certislam::actors {

DescriptorActor::DescriptorActor(zmq::context_t& context, TeamWiring wiring,
                                 slam::ScanContextConfig config)
    : NodeActor("descriptor", context, std::move(wiring)), config_(config) {
    config_.Validate();
}

void DescriptorActor::OnStart() {
    out_ = &OpenServer(Edge::kDescriptors);
    OpenClient(Edge::kKeyframes, RobotId());
    On(v1::Keyframe::descriptor()->full_name(), [this](const transport::Message& m) {
        const auto keyframe = DecodeKeyframe(m);
        if (!keyframe || keyframe->robot != RobotId()) return false;
        // A keyframe sent again is described once: the end marker counts distinct descriptors.
        if (!described_.insert(keyframe->index).second) return true;
        const auto sc = slam::MakeScanContext(*keyframe->cloud, config_);
        auto proto = ToProto(sc, {keyframe->robot, keyframe->index});
        *proto.mutable_header() = MakeHeader(RobotId(), NextSequence(), keyframe->stamp_ns);
        sent_.push_back(transport::Pack(proto));
        Send(*out_, sent_.back(), true);
        return true;
    });
    On(v1::Shutdown::descriptor()->full_name(), [this](const transport::Message& m) {
        const auto end = transport::Unpack<v1::Shutdown>(m);
        if (!end) return false;
        if (end->reason() == kEndOfKeyframes && !ended_) {
            ended_ = true;
            SendEnd();
        }
        return true;
    });
    Every(std::chrono::milliseconds(500), [this] {
        if (ended_) SendEnd();
    });
    Every(std::chrono::milliseconds(100), [this] { Resync(); });
}

void DescriptorActor::Resync() {
    // A subscriber that (re)joined after we published (a restarted peer) gets everything again;
    // matchers ignore descriptors they already hold.
    const std::size_t now = out_->subscribers();
    if (now > seen_subscribers_ && !sent_.empty()) {
        for (const auto& message : sent_) Send(*out_, message, true);
        if (ended_) SendEnd();
    }
    seen_subscribers_ = now;
}

void DescriptorActor::SendEnd() {
    v1::Shutdown end;
    *end.mutable_header() = MakeHeader(RobotId(), NextSequence(), 0);
    end.set_reason(kEndOfDescriptors);
    end.set_count(sent_.size());  // a matcher holding fewer waits for the re-sent ones
    Send(*out_, transport::Pack(end), true);
}

}  // namespace certislam::actors
