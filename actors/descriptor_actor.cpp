// Descriptor: Keyframe in, Scan Context out (to own and peers' loop matchers).
#include "actors/descriptor_actor.h"

#include "actors/codec.h"
#include "actors/ingest_actor.h"
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
        const auto sc = slam::MakeScanContext(*keyframe->cloud, config_);
        auto proto = ToProto(sc, {keyframe->robot, keyframe->index});
        *proto.mutable_header() = MakeHeader(RobotId(), NextSequence(), keyframe->stamp_ns);
        Send(*out_, transport::Pack(proto), true);
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
}

void DescriptorActor::SendEnd() {
    v1::Shutdown end;
    *end.mutable_header() = MakeHeader(RobotId(), NextSequence(), 0);
    end.set_reason(kEndOfDescriptors);
    Send(*out_, transport::Pack(end), true);
}

}  // namespace certislam::actors
