// Strict decoding and encoding of the frames of a certislam message.
#include "transport/message.h"

#include <climits>
#include <cstdint>
#include <stdexcept>

namespace certislam::transport {

std::size_t Message::ByteSize() const {
    std::size_t bytes = envelope.ByteSizeLong();
    for (const auto& frame : frames) bytes += frame.size();
    return bytes;
}

void AppendFrame(Message& message, SharedBuffer frame, v1::FrameKind kind) {
    auto* info = message.envelope.add_frames();
    info->set_kind(kind);
    info->set_byte_length(frame.size());
    if (kind == v1::FRAME_KIND_INLINE) info->set_payload_byte_length(frame.size());
    message.frames.push_back(std::move(frame));
}

void DecodeLimits::Validate() const {
    auto require_positive = [](std::size_t value, const char* field) {
        if (value == 0) {
            throw std::invalid_argument(std::string("DecodeLimits.") + field +
                                        " = 0: must be positive");
        }
    };
    require_positive(max_envelope_bytes, "max_envelope_bytes");
    require_positive(max_frames, "max_frames");
    require_positive(max_frame_bytes, "max_frame_bytes");
}

const char* ToString(DecodeResult::Status status) {
    switch (status) {
        case DecodeResult::Status::kOk:
            return "ok";
        case DecodeResult::Status::kEmpty:
            return "empty";
        case DecodeResult::Status::kMalformed:
            return "malformed";
        case DecodeResult::Status::kUnsupportedVersion:
            return "unsupported version";
        case DecodeResult::Status::kFrameCountMismatch:
            return "frame count mismatch";
        case DecodeResult::Status::kFrameSizeMismatch:
            return "frame size mismatch";
        case DecodeResult::Status::kTooLarge:
            return "too large";
    }
    return "unknown";
}

namespace {

DecodeResult Fail(DecodeResult::Status status, std::string detail) {
    DecodeResult result;
    result.status = status;
    result.detail = std::move(detail);
    return result;
}

bool KnownFrameKind(v1::FrameKind kind) {
    return kind == v1::FRAME_KIND_INLINE || kind == v1::FRAME_KIND_SHM_DESCRIPTOR;
}

// Checks the envelope's fields and its frame table against the frames that came with it.
DecodeResult Validate(const v1::Envelope& envelope, const std::vector<SharedBuffer>& frames) {
    using Status = DecodeResult::Status;
    if (envelope.schema_major() == 0 || envelope.type_name().empty()) {
        return Fail(Status::kMalformed, "envelope lacks schema_major or type_name");
    }
    if (envelope.schema_major() != kSchemaMajor) {
        return Fail(Status::kUnsupportedVersion, "schema major " +
                                                     std::to_string(envelope.schema_major()) +
                                                     ", expected " + std::to_string(kSchemaMajor));
    }
    if (static_cast<std::size_t>(envelope.frames_size()) != frames.size()) {
        return Fail(Status::kFrameCountMismatch,
                    "envelope declares " + std::to_string(envelope.frames_size()) +
                        " frames, got " + std::to_string(frames.size()));
    }
    for (std::size_t i = 0; i < frames.size(); ++i) {
        const auto& info = envelope.frames(static_cast<int>(i));
        if (!KnownFrameKind(info.kind())) {
            return Fail(Status::kMalformed, "frame " + std::to_string(i) + " has unknown kind");
        }
        if (info.byte_length() != frames[i].size()) {
            return Fail(Status::kFrameSizeMismatch, "frame " + std::to_string(i) + " declares " +
                                                        std::to_string(info.byte_length()) +
                                                        " bytes, got " +
                                                        std::to_string(frames[i].size()));
        }
    }
    return DecodeResult{Status::kOk, std::nullopt, {}};
}

}  // namespace

DecodeResult DecodeBytes(std::span<const std::byte> envelope_bytes,
                         std::vector<SharedBuffer> frames, const DecodeLimits& limits) {
    using Status = DecodeResult::Status;
    if (envelope_bytes.size() > limits.max_envelope_bytes) {
        return Fail(Status::kTooLarge, "envelope of " + std::to_string(envelope_bytes.size()) +
                                           " bytes over the limit");
    }
    if (frames.size() > limits.max_frames) {
        return Fail(Status::kTooLarge, std::to_string(frames.size()) + " frames over the limit");
    }
    for (const auto& frame : frames) {
        if (frame.size() > limits.max_frame_bytes) {
            return Fail(Status::kTooLarge, "binary frame over the limit");
        }
    }
    Message message;
    if (envelope_bytes.size() > static_cast<std::size_t>(INT32_MAX) ||
        !message.envelope.ParseFromArray(envelope_bytes.data(),
                                         static_cast<int>(envelope_bytes.size()))) {
        return Fail(Status::kMalformed, "envelope bytes do not parse");
    }
    DecodeResult result = Validate(message.envelope, frames);
    if (result.status != Status::kOk) return result;
    message.frames = std::move(frames);
    result.message = std::move(message);
    return result;
}

DecodeResult Decode(std::vector<zmq::message_t>&& frames, const DecodeLimits& limits) {
    if (frames.empty()) return Fail(DecodeResult::Status::kEmpty, "no frames");
    if (frames.size() - 1 > limits.max_frames) {
        return Fail(DecodeResult::Status::kTooLarge,
                    std::to_string(frames.size() - 1) + " frames over the limit");
    }
    std::vector<SharedBuffer> binary;
    binary.reserve(frames.size() - 1);
    for (std::size_t i = 1; i < frames.size(); ++i) {
        binary.push_back(SharedBuffer::FromZmq(std::move(frames[i])));
    }
    const auto* data = static_cast<const std::byte*>(frames[0].data());
    return DecodeBytes({data, frames[0].size()}, std::move(binary), limits);
}

std::vector<zmq::message_t> Encode(const Message& message) {
    std::vector<zmq::message_t> frames;
    frames.reserve(message.frames.size() + 1);
    std::string envelope = message.envelope.SerializeAsString();
    frames.emplace_back(envelope.data(), envelope.size());
    for (const auto& frame : message.frames) frames.push_back(ToZmqFrame(frame));
    return frames;
}

}  // namespace certislam::transport
