// A certislam message (protobuf envelope + binary frames), its typed packing, and strict decoding
// of the ZeroMQ frames it travels in.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>
#include <zmq.hpp>

#include "certislam/v1/envelope.pb.h"
#include "transport/buffer.h"

namespace certislam::transport {

/// Schema major version this build speaks; a different major on the wire is rejected.
inline constexpr std::uint32_t kSchemaMajor = 1;
/// Schema minor version this build writes; any minor of the same major is accepted.
inline constexpr std::uint32_t kSchemaMinor = 0;

/// One message: the envelope (header, version, type, payload bytes, frame table) and the binary
/// frames that follow it. In-process, frames are shared handles, never copies.
struct Message {
    v1::Envelope envelope;             ///< frame 0 on the wire
    std::vector<SharedBuffer> frames;  ///< frames 1..n; frames[i] matches envelope.frames(i)
    std::string peer;     ///< routing id of the sender on a ROUTER socket (empty otherwise)
    std::string user_id;  ///< ZAP user id of an authenticated (CURVE) sender, else empty

    /// Full protobuf name of the payload type, e.g. "certislam.v1.Keyframe".
    const std::string& type_name() const { return envelope.type_name(); }
    /// True when the payload is of type T.
    template <class T>
    bool Is() const {
        return envelope.type_name() == T::descriptor()->full_name();
    }
    /// Sum of the envelope's and the frames' sizes (what queue byte limits count).
    std::size_t ByteSize() const;
};

/// Wraps a payload in an envelope (current schema version, its type name, a copy of its header
/// when it has one) and appends the binary frames as FRAME_KIND_INLINE.
template <class T>
Message Pack(const T& payload, std::vector<SharedBuffer> frames = {});

/// Appends one binary frame of the given kind (e.g. a serialized ShmDescriptor) to a message.
void AppendFrame(Message& message, SharedBuffer frame, v1::FrameKind kind = v1::FRAME_KIND_INLINE);

/// The payload as T, or nullopt when the message holds another type or its bytes do not parse.
template <class T>
std::optional<T> Unpack(const Message& message);

/// Limits a decoder enforces on untrusted frames.
struct DecodeLimits {
    std::size_t max_envelope_bytes = 64u << 20;  ///< size of frame 0
    std::size_t max_frames = 16;                 ///< binary frames after the envelope
    std::size_t max_frame_bytes = 1u << 30;      ///< size of one binary frame

    /// Throws std::invalid_argument naming a field that is zero.
    void Validate() const;
};

/// The outcome of decoding the frames of one message.
struct DecodeResult {
    /// Every way decoding can end.
    enum class Status {
        kOk,
        kEmpty,               ///< no frames at all
        kMalformed,           ///< envelope bytes do not parse, or required fields are missing
        kUnsupportedVersion,  ///< schema_major differs from kSchemaMajor
        kFrameCountMismatch,  ///< binary frame count differs from the envelope's frame table
        kFrameSizeMismatch,   ///< a binary frame's size differs from its declared byte_length
        kTooLarge,            ///< over a DecodeLimits bound
    };
    Status status = Status::kEmpty;
    std::optional<Message> message;  ///< set when status == kOk
    std::string detail;              ///< human-readable reason when not kOk
};

/// Short name of a status ("ok", "malformed", ...).
const char* ToString(DecodeResult::Status status);

/// Decodes frames [envelope, binary...] (routing id already removed). Never throws on any
/// bytes; binary frames are adopted without copying.
DecodeResult Decode(std::vector<zmq::message_t>&& frames, const DecodeLimits& limits = {});

/// Decodes an envelope from raw bytes with the given binary frames (the fuzzer's entry point).
DecodeResult DecodeBytes(std::span<const std::byte> envelope_bytes,
                         std::vector<SharedBuffer> frames, const DecodeLimits& limits = {});

/// Encodes a message into ZeroMQ frames: [envelope, binary...]. Binary frames are not copied.
std::vector<zmq::message_t> Encode(const Message& message);

// ---- template definitions ----

template <class T>
Message Pack(const T& payload, std::vector<SharedBuffer> frames) {
    Message message;
    message.envelope.set_schema_major(kSchemaMajor);
    message.envelope.set_schema_minor(kSchemaMinor);
    message.envelope.set_type_name(T::descriptor()->full_name());
    if constexpr (requires { payload.header(); }) {
        *message.envelope.mutable_header() = payload.header();
    }
    payload.SerializeToString(message.envelope.mutable_payload());
    for (auto& frame : frames) AppendFrame(message, std::move(frame));
    return message;
}

template <class T>
std::optional<T> Unpack(const Message& message) {
    if (!message.Is<T>()) return std::nullopt;
    T payload;
    if (!payload.ParseFromString(message.envelope.payload())) return std::nullopt;
    return payload;
}

}  // namespace certislam::transport
