// The byte layout a fuzzer input uses to stand for one multipart ZeroMQ message, shared by the
// envelope fuzzer and the program that writes its seed corpus.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>
#include <zmq.hpp>

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

}  // namespace certislam::fuzz
