// Compact wire form of a Scan Context descriptor (what robots send every peer per keyframe):
// bin heights quantised to a fixed step as uint16, byte-planed and compressed with zstd.
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include "slam/frontend/scan_context.h"

namespace certislam::slam {

/// Settings of the compact descriptor encoder.
struct ScanContextCompressionConfig {
    double height_step_m = 0.05;  ///< quantisation of bin heights, (0, 1]: error <= step / 2
    int zstd_level = 19;          ///< zstd level, [1, 19]: higher is smaller and slower to encode

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// Encodes `descriptor` (heights above 65535 steps are clamped; negative ones become 0).
/// Validates `config` (throws std::invalid_argument).
std::vector<std::uint8_t> EncodeScanContextCompact(const ScanContext& descriptor,
                                                   const ScanContextCompressionConfig& config = {});

/// Decodes EncodeScanContextCompact's bytes (ring and sector keys recomputed from the bins);
/// std::nullopt when malformed (untrusted input).
std::optional<ScanContext> DecodeScanContextCompact(const std::vector<std::uint8_t>& bytes);

}  // namespace certislam::slam
