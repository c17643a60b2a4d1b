// Bytes robots exchange per keyframe in the loop stage (descriptors to every peer, clouds of
// inter-robot candidates) with and without the compact compressions and the cloud-request gate, and
// the precision of the loops verified on the decoded clouds.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace certislam::bin {

/// Loops and bytes through one cloud-request gate setting (decoded clouds, PCM).
struct GatedFigures {
    int place_window = 0;         ///< the gate's window (0: every distinct cloud once)
    int fetches = 0;              ///< clouds fetched
    double clouds_encoded = 0.0;  ///< their encoded bytes per keyframe
    int loops = 0;                ///< accepted loops
    int inter_loops = 0;          ///< of which inter-robot
    int wrong_loops = 0;          ///< off the truth by >= 0.5 m or 2 degrees
};

/// One mission's figures (bytes are per keyframe of the whole team unless named otherwise).
struct BandwidthFigures {
    std::string mission;               ///< name
    int keyframes = 0;                 ///< over all robots
    int inter_candidates = 0;          ///< Scan Context inter-robot candidates
    double descriptor_float = 0.0;     ///< SerializeScanContext bytes to peers
    double descriptor_compact = 0.0;   ///< EncodeScanContextCompact bytes to peers
    double clouds_float_all = 0.0;     ///< every inter candidate's cloud, float32 at the voxel
    double clouds_encoded_all = 0.0;   ///< the same, EncodeCloud
    double baseline_cloud = 0.0;       ///< mean keyframe cloud at the voxel, float32
    double baseline_cloud_0_2m = 0.0;  ///< mean keyframe cloud at 0.2 m, float32
    std::vector<GatedFigures> gated;   ///< per gate setting
    double seconds = 0.0;              ///< wall time of the measurement

    /// As JSON with the ratios against the baseline cloud.
    nlohmann::json ToJson() const;
};

/// The default simulated two-robot mission and KAIST03 split into two robots (even/odd).
std::vector<BandwidthFigures> MeasureMissionBandwidth(const std::string& kaist_folder);

}  // namespace certislam::bin
