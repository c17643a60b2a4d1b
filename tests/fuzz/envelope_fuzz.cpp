// libFuzzer target of the envelope decoder: arbitrary bytes stand for the frames of one multipart
// message (fuzz_frames.h). The decoder must never crash, and what it accepts must round-trip.
#include <google/protobuf/descriptor.h>
#include <google/protobuf/message.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <span>

#include "tests/fuzz/fuzz_frames.h"
#include "tests/fuzz/fuzz_quiet_protobuf.h"
#include "tests/fuzz/fuzz_types.h"
#include "transport/message.h"
#include "transport/shm_segment.h"

namespace certislam::fuzz {
namespace {

using transport::DecodeResult;
using Status = DecodeResult::Status;

// Small limits so that the fuzzer reaches the "too large" paths with small inputs.
transport::DecodeLimits FuzzLimits() {
    transport::DecodeLimits limits;
    limits.max_envelope_bytes = 1u << 16;
    limits.max_frames = 8;
    limits.max_frame_bytes = 1u << 16;
    return limits;
}

[[noreturn]] void Fail(const char* what, const DecodeResult& result) {
    std::fprintf(stderr, "envelope fuzz: %s (status %s: %s)\n", what, ToString(result.status),
                 result.detail.c_str());
    std::abort();
}

// Parses the payload as the type the envelope names, when the schemas know it.
void ParsePayload(const transport::Message& message) {
    const auto* descriptor =
        google::protobuf::DescriptorPool::generated_pool()->FindMessageTypeByName(
            message.type_name());
    if (descriptor == nullptr) return;
    const auto* prototype =
        google::protobuf::MessageFactory::generated_factory()->GetPrototype(descriptor);
    std::unique_ptr<google::protobuf::Message> payload(prototype->New());
    if (payload->ParseFromString(message.envelope.payload())) (void)payload->ByteSizeLong();
}

// Parses every shared-memory descriptor frame (never opens it: that is the ShmReader's test).
void ParseShmFrames(const transport::Message& message) {
    for (int i = 0; i < message.envelope.frames_size(); ++i) {
        if (message.envelope.frames(i).kind() != v1::FRAME_KIND_SHM_DESCRIPTOR) continue;
        const auto& frame = message.frames[static_cast<std::size_t>(i)];
        v1::ShmDescriptor proto;
        if (proto.ParseFromArray(frame.data(), static_cast<int>(frame.size()))) {
            (void)transport::FromProto(proto);
        }
    }
}

// What the decoder accepted must encode and decode to the same envelope and frames.
void CheckRoundTrip(const transport::Message& message) {
    DecodeResult again = transport::Decode(transport::Encode(message), FuzzLimits());
    if (again.status != Status::kOk || !again.message) Fail("re-encoded message rejected", again);
    if (again.message->envelope.SerializeAsString() != message.envelope.SerializeAsString()) {
        Fail("envelope changed on a round trip", again);
    }
    if (again.message->frames.size() != message.frames.size()) Fail("frame count changed", again);
    for (std::size_t i = 0; i < message.frames.size(); ++i) {
        const auto a = message.frames[i].span();
        const auto b = again.message->frames[i].span();
        if (a.size() != b.size() || !std::equal(a.begin(), a.end(), b.begin())) {
            Fail("frame bytes changed on a round trip", again);
        }
    }
}

}  // namespace
}  // namespace certislam::fuzz

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    using namespace certislam;
    static const auto kTypes = fuzz::AllMessageTypes();  // links and registers every schema
    (void)kTypes;
    auto frames = fuzz::SplitFrames({data, size});
    const bool had_frames = !frames.empty();
    const transport::DecodeResult result = transport::Decode(std::move(frames), fuzz::FuzzLimits());
    if (result.status != fuzz::Status::kOk) {
        if (result.message) fuzz::Fail("a rejected message carries a value", result);
        if (had_frames && result.status == fuzz::Status::kEmpty) fuzz::Fail("frames lost", result);
        return 0;
    }
    if (!result.message) fuzz::Fail("an accepted message carries no value", result);
    if (result.message->envelope.schema_major() != transport::kSchemaMajor) {
        fuzz::Fail("accepted another schema major", result);
    }
    fuzz::ParsePayload(*result.message);
    fuzz::ParseShmFrames(*result.message);
    fuzz::CheckRoundTrip(*result.message);
    return 0;
}
