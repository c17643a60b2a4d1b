// The byte layout a fuzzer input uses to stand for one multipart ZeroMQ message, shared by the
// fuzzers and the programs that write their seed corpora.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>
#include <zmq.hpp>

#include "transport/message.h"

namespace certislam::fuzz {

/// Most frames one input is split into (the decoder's own limit is lower, so it is exercised).
inline constexpr std::size_t kMaxFuzzFrames = 24;

/// Splits an input into frames: each frame is a 4-byte little-endian length and that many bytes;
/// a length running past the end takes what is left. Frame 0 is the envelope.
inline std::vector<zmq::message_t> SplitFrames(std::span<const std::uint8_t> input) {
    std::vector<zmq::message_t> frames;
    std::size_t at = 0;
    while (at < input.size() && frames.size() < kMaxFuzzFrames) {
        std::uint32_t length = 0;
        for (std::size_t i = 0; i < 4; ++i) {
            const std::size_t k = at + i;
            length |= static_cast<std::uint32_t>(k < input.size() ? input[k] : 0) << (8 * i);
        }
        at = std::min(at + 4, input.size());
        const std::size_t take = std::min<std::size_t>(length, input.size() - at);
        frames.emplace_back(input.data() + at, take);
        at += take;
    }
    return frames;
}

/// The inverse of SplitFrames: the input that stands for these frames.
inline std::string JoinFrames(const std::vector<zmq::message_t>& frames) {
    std::string out;
    for (const auto& frame : frames) {
        const auto length = static_cast<std::uint32_t>(frame.size());
        for (int i = 0; i < 4; ++i) out.push_back(static_cast<char>((length >> (8 * i)) & 0xffu));
        out.append(static_cast<const char*>(frame.data()), frame.size());
    }
    return out;
}

/// The frames of `message` as a peer's message body arrives: the payload, then its binary frames.
inline std::vector<zmq::message_t> BodyFrames(const transport::Message& message) {
    std::vector<zmq::message_t> frames;
    frames.emplace_back(message.envelope.payload().data(), message.envelope.payload().size());
    for (const auto& frame : message.frames) frames.emplace_back(frame.data(), frame.size());
    return frames;
}

/// The inverse of BodyFrames: frame 0 parsed as T, the other frames attached; nullopt when frame 0
/// is not a T.
template <class T>
std::optional<transport::Message> BodyMessage(const std::vector<zmq::message_t>& frames) {
    T payload;
    if (frames.empty() ||
        !payload.ParseFromArray(frames[0].data(), static_cast<int>(frames[0].size()))) {
        return std::nullopt;
    }
    std::vector<transport::SharedBuffer> binary;
    for (std::size_t i = 1; i < frames.size(); ++i) {
        binary.push_back(transport::SharedBuffer::Copy(frames[i].data(), frames[i].size()));
    }
    return transport::Pack(payload, std::move(binary));
}

}  // namespace certislam::fuzz
