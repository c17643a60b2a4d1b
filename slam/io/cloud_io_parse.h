// Parsing helpers shared by the PCD and PLY readers (cloud_io_pcd.cpp, cloud_io_ply.cpp): scalar
// decoding, header words, numbers, lines. Internal to the cloud readers, not part of the public
// API.
#pragma once

#include <bit>
#include <cstdint>
#include <cstring>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "slam/io/cloud_read_result.h"

namespace certislam::slam::cloud_io_internal {

static_assert(std::endian::native == std::endian::little,
              "the binary cloud readers assume a little-endian host");

/// How a scalar is stored: signed integer, unsigned integer or IEEE float.
enum class ScalarKind { kInt, kUint, kFloat };

/// A stored scalar type: kind and size in bytes (1, 2, 4 or 8; floats 4 or 8).
struct ScalarType {
    ScalarKind kind = ScalarKind::kFloat;
    int size = 4;
};

/// Decodes one little-endian scalar at `p` as a double.
inline double DecodeScalar(const unsigned char* p, ScalarType type) {
    switch (type.kind) {
        case ScalarKind::kFloat:
            if (type.size == 4) {
                float v;
                std::memcpy(&v, p, 4);
                return v;
            } else {
                double v;
                std::memcpy(&v, p, 8);
                return v;
            }
        case ScalarKind::kInt: {
            std::int64_t v = 0;
            std::memcpy(&v, p, static_cast<std::size_t>(type.size));
            const int shift = 64 - 8 * type.size;  // sign-extend
            return static_cast<double>(
                static_cast<std::int64_t>(static_cast<std::uint64_t>(v) << shift) >> shift);
        }
        case ScalarKind::kUint: {
            std::uint64_t v = 0;
            std::memcpy(&v, p, static_cast<std::size_t>(type.size));
            return static_cast<double>(v);
        }
    }
    return 0.0;
}

/// a * b, or std::nullopt when the product does not fit in size_t (sizes from a file header).
inline std::optional<std::size_t> CheckedMul(std::size_t a, std::size_t b) {
    std::size_t out = 0;
    if (__builtin_mul_overflow(a, b, &out)) return std::nullopt;
    return out;
}

/// a + b, or std::nullopt when the sum does not fit in size_t.
inline std::optional<std::size_t> CheckedAdd(std::size_t a, std::size_t b) {
    std::size_t out = 0;
    if (__builtin_add_overflow(a, b, &out)) return std::nullopt;
    return out;
}

/// Largest cloud file read (whole, into memory): far above any LiDAR scan (a 128-beam scan is
/// ~10 MB), so a larger file is refused before it is loaded.
inline constexpr std::size_t kMaxCloudFileBytes = std::size_t{2} << 30;

/// Reads a whole file; std::nullopt when it cannot be opened or read, or exceeds
/// kMaxCloudFileBytes (then *too_big is set when given).
std::optional<std::vector<unsigned char>> ReadFileBytes(const std::string& path,
                                                        bool* too_big = nullptr);

/// The error for a file that could not be read (or was over kMaxCloudFileBytes).
CloudReadResult ReadFailure(const std::string& path, bool too_big);

/// A failed result with status and "PATH: message" (or "PATH:LINE: message" when line > 0).
CloudReadResult Fail(CloudReadResult::Status status, const std::string& path, int line,
                     const std::string& message);

/// Appends (x, y, z) to `result.cloud` when finite, else counts it in dropped_non_finite.
inline void AddPoint(CloudReadResult& result, double x, double y, double z) {
    const Eigen::Vector3f p(static_cast<float>(x), static_cast<float>(y), static_cast<float>(z));
    if (p.allFinite()) {
        result.cloud.push_back(p);
    } else {
        ++result.dropped_non_finite;
    }
}

/// Splits a header line on spaces/tabs (dropping a trailing '\r').
std::vector<std::string_view> SplitWords(std::string_view line);

/// Parses a whole word as a number; std::nullopt when it is not one.
std::optional<double> ParseDouble(std::string_view word);

/// Parses a whole word as a non-negative integer; std::nullopt when it is not one.
std::optional<long long> ParseCount(std::string_view word);

/// One line of a text region: the text and the offset just past its '\n' (or the end).
struct LineView {
    std::string_view text;
    std::size_t next = 0;
};

/// The line of `bytes` starting at `offset` (offset < bytes.size()).
LineView NextLine(const std::vector<unsigned char>& bytes, std::size_t offset);

}  // namespace certislam::slam::cloud_io_internal
