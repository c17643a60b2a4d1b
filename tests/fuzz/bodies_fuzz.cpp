// libFuzzer target of the message body decoders the actors accept from peers (actors/convert.h):
// byte 0 picks the body, the rest stands for its frames (fuzz_frames.h; frame 0 the protobuf
// payload, the others its binary frames). A decoder must never crash, and what it accepts must be
// finite and within its documented rules.
#include <google/protobuf/stubs/logging.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <span>

#include "actors/convert.h"
#include "tests/fuzz/fuzz_frames.h"
#include "transport/message.h"

namespace certislam::fuzz {
namespace {

[[noreturn]] void Fail(const char* what) {
    std::fprintf(stderr, "bodies fuzz: %s\n", what);
    std::abort();
}

bool Finite(const Eigen::Isometry3d& T) { return T.matrix().allFinite(); }

// The payload parsed as T (frame 0) with the other frames attached, as a peer's message arrives.
template <class T>
std::optional<transport::Message> AsMessage(std::vector<zmq::message_t>& frames) {
    if (frames.empty()) return std::nullopt;
    T payload;
    if (!payload.ParseFromArray(frames[0].data(), static_cast<int>(frames[0].size()))) {
        return std::nullopt;
    }
    std::vector<transport::SharedBuffer> binary;
    for (std::size_t i = 1; i < frames.size(); ++i) {
        binary.push_back(transport::SharedBuffer::Copy(frames[i].data(), frames[i].size()));
    }
    return transport::Pack(payload, std::move(binary));
}

template <class T>
std::optional<T> Parse(const std::vector<zmq::message_t>& frames) {
    T payload;
    if (frames.empty() ||
        !payload.ParseFromArray(frames[0].data(), static_cast<int>(frames[0].size()))) {
        return std::nullopt;
    }
    return payload;
}

void Keyframe(std::vector<zmq::message_t>& frames) {
    const auto message = AsMessage<v1::Keyframe>(frames);
    if (!message) return;
    const auto keyframe = actors::DecodeKeyframe(*message);
    if (keyframe && (!Finite(keyframe->T_odom_sensor) || !keyframe->cloud)) {
        Fail("accepted keyframe with a non-finite pose or no cloud");
    }
}

void CloudReply(std::vector<zmq::message_t>& frames) {
    const auto message = AsMessage<v1::CloudReply>(frames);
    if (!message) return;
    v1::CloudReply reply;
    const auto cloud = actors::DecodeCloudReply(*message, &reply);
    if (cloud && !*cloud) Fail("accepted cloud reply without a cloud");
}

void Descriptor(const std::vector<zmq::message_t>& frames) {
    const auto proto = Parse<v1::ScanContextDescriptor>(frames);
    if (!proto) return;
    const auto sc = actors::FromProto(*proto);
    if (sc && (!sc->bins.allFinite() || !sc->ring_key.allFinite())) {
        Fail("accepted descriptor with non-finite values");
    }
}

void Loop(const std::vector<zmq::message_t>& frames) {
    const auto proto = Parse<v1::LoopClosure>(frames);
    if (!proto) return;
    (void)actors::WithdrawnEnds(*proto);
    const auto loop = actors::FromProto(*proto);
    if (loop && (!Finite(loop->T_a_b) || !(loop->kappa > 0) || !(loop->tau > 0))) {
        Fail("accepted loop closure with a non-finite pose or a weight not > 0");
    }
}

void Poses(const std::vector<zmq::message_t>& frames) {
    const auto proto = Parse<v1::PublicPoses>(frames);
    if (!proto) return;
    (void)actors::FromProto(*proto);
}

void Trajectory(const std::vector<zmq::message_t>& frames) {
    const auto proto = Parse<v1::TrajectoryUpdate>(frames);
    if (!proto) return;
    const auto poses = actors::TrajectoryFromProto(*proto);
    if (!poses) return;
    for (const auto& [id, T] : *poses) {
        if (!Finite(T)) Fail("accepted trajectory with a non-finite pose");
    }
}

}  // namespace
}  // namespace certislam::fuzz

// Payload strings with invalid UTF-8 make protobuf log an error per input: keep the output legible.
extern "C" int LLVMFuzzerInitialize(int* /*argc*/, char*** /*argv*/) {
    google::protobuf::SetLogHandler(nullptr);
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    using namespace certislam::fuzz;
    if (size == 0) return 0;
    auto frames = SplitFrames({data + 1, size - 1});
    switch (data[0] % 6) {
        case 0:
            Keyframe(frames);
            break;
        case 1:
            CloudReply(frames);
            break;
        case 2:
            Descriptor(frames);
            break;
        case 3:
            Loop(frames);
            break;
        case 4:
            Poses(frames);
            break;
        default:
            Trajectory(frames);
            break;
    }
    return 0;
}
