// Compact wire form of a point cloud for the clouds robots exchange to verify a loop candidate:
// coordinates quantised to a fixed step relative to the sensor, Morton-ordered, delta-coded
// per axis, byte-planed and compressed with zstd. Lossy by at most half a step per axis.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "slam/core/keyframe.h"

namespace certislam::slam {

/// Settings of the cloud encoder.
struct CloudCompressionConfig {
    double resolution_m = 0.01;  ///< quantisation step, (0, 1]: error <= resolution_m / 2 per axis
    int zstd_level = 9;          ///< zstd compression level, [1, 19]

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// An encoded cloud.
struct CloudEncodeResult {
    std::vector<std::uint8_t> bytes;  ///< the wire form (header + zstd frame)
    int points_dropped = 0;           ///< points farther than 32767 steps on an axis, or not finite
};

/// Encodes `cloud` (sensor frame, so coordinates stay within 32767 * resolution_m). Point order
/// is not kept (points come back in Morton order); validates `config` (throws
/// std::invalid_argument).
CloudEncodeResult EncodeCloud(const PointCloud& cloud, const CloudCompressionConfig& config = {});

/// A decoded cloud.
struct CloudDecodeResult {
    enum class Status {
        kOk,         ///< `cloud` holds the points
        kMalformed,  ///< bad magic, header, sizes or compressed data
    };
    Status status = Status::kOk;  ///< verdict
    PointCloud cloud;             ///< the points (empty unless kOk)
    double resolution_m = 0.0;    ///< the step they were quantised with
    std::string error;            ///< what was wrong (empty when kOk)

    /// True when the bytes decoded.
    bool ok() const { return status == Status::kOk; }
};

/// Decodes EncodeCloud's bytes; untrusted input: any malformation is a kMalformed result.
CloudDecodeResult DecodeCloud(const std::uint8_t* data, std::size_t size);

/// Decodes EncodeCloud's bytes held in a vector.
inline CloudDecodeResult DecodeCloud(const std::vector<std::uint8_t>& bytes) {
    return DecodeCloud(bytes.data(), bytes.size());
}

/// True when `size` bytes at `data` start with the encoded-cloud magic (cheap format sniffing).
bool IsEncodedCloud(const std::uint8_t* data, std::size_t size);

}  // namespace certislam::slam
