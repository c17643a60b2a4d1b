// Scan Context place descriptor (Kim & Kim, IROS 2018): polar max-height grid, ring and sector
// keys, and the column-shift distance with the yaw it implies. Written from the paper.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <vector>

#include "slam/core/keyframe.h"

namespace certislam::slam {

/// Settings of the descriptor and of its distance search.
struct ScanContextConfig {
    int num_rings = 20;              ///< radial bins N_r (paper Sec. III-A), >= 1
    int num_sectors = 60;            ///< azimuthal bins N_s, >= 2 (6 degrees each by default)
    double max_range_m = 80.0;       ///< L_max: points farther (horizontally) are ignored, > 0
    double sensor_height_m = 2.0;    ///< added to z so ground heights are positive; empty bin = 0
    double fast_search_ratio = 0.1;  ///< fast distance: search +-ratio*N_s shifts around the
                                     ///< sector-key alignment, in (0, 0.5]

    /// Throws std::invalid_argument naming the field, its value and the rule.
    void Validate() const;
};

/// Ring-major float matrix (row = ring, column = sector): the layout of the wire format.
using ScanContextMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

/// One descriptor. Sector j covers azimuth [j, j+1) * 2pi/N_s, counter-clockwise from +x.
struct ScanContext {
    ScanContextMatrix bins;      ///< N_r x N_s max height (+ sensor_height_m) per bin, 0 if empty
    Eigen::VectorXf ring_key;    ///< N_r: mean of each ring over sectors (rotation invariant)
    Eigen::VectorXf sector_key;  ///< N_s: mean of each sector over rings (for coarse alignment)
    double max_range_m = 80.0;   ///< L_max it was built with
};

/// Builds the descriptor of a cloud in the sensor frame (z up). Paper Sec. III-A, Eq. (1)-(2).
ScanContext MakeScanContext(const PointCloud& cloud, const ScanContextConfig& config);

/// The best column alignment of two descriptors.
struct ScanContextMatch {
    double distance = 1.0;  ///< mean cosine distance over column pairs that are both non-empty,
                            ///< in [0, 1] (1 when no pair is non-empty)
    int shift = 0;          ///< query column j matches candidate column (j + shift) mod N_s
    double yaw_rad = 0.0;   ///< shift * 2pi/N_s wrapped to (-pi, pi]: the yaw of the query scan
                            ///< in the candidate's frame, i.e. T_candidate_query ~ Rz(yaw_rad)
};

/// The distance at one column shift (paper Eq. (5)).
double ScanContextDistanceAtShift(const ScanContext& query, const ScanContext& candidate,
                                  int shift);

/// Exhaustive search over all N_s column shifts (paper Eq. (6)).
ScanContextMatch ScanContextDistance(const ScanContext& query, const ScanContext& candidate);

/// A descriptor's columns scaled to unit length (empty columns stay zero), as Eq. (5) compares
/// them: made once per stored descriptor, it serves every exhaustive search against it.
struct ScanContextColumns {
    explicit ScanContextColumns(const ScanContext& sc);
    Eigen::MatrixXf columns;              ///< N_r x N_s, column-major
    std::vector<std::uint8_t> non_empty;  ///< 1 where the column is not all zero
};

/// ScanContextDistance on columns made beforehand: the same result, bit for bit.
ScanContextMatch ScanContextDistance(const ScanContextColumns& query,
                                     const ScanContextColumns& candidate);

/// Fast search: coarse shift from the sector keys, then +-search_radius shifts around it.
ScanContextMatch ScanContextDistanceFast(const ScanContext& query, const ScanContext& candidate,
                                         int search_radius);

/// The fast search with its radius from `config` (round(fast_search_ratio * N_s), at least 1).
ScanContextMatch ScanContextDistanceFast(const ScanContext& query, const ScanContext& candidate,
                                         const ScanContextConfig& config);

/// The wire form: magic, N_r, N_s, max range, then ring-major bins and the ring key (float32,
/// little-endian). The sector key is recomputed on reading.
std::vector<std::uint8_t> SerializeScanContext(const ScanContext& descriptor);

/// Parses SerializeScanContext's bytes; std::nullopt when malformed (wrong magic or size).
std::optional<ScanContext> DeserializeScanContext(const std::vector<std::uint8_t>& bytes);

}  // namespace certislam::slam
