// Readers and writers of point-cloud files (KITTI .bin, PCD, PLY) with errors naming file and
// fault.
#pragma once

#include <string>

#include "slam/core/keyframe.h"

namespace certislam::slam {

/// The outcome of reading a point-cloud file. Readers never throw on bad files.
struct CloudReadResult {
    enum class Status {
        kOk,           ///< `cloud` holds the points
        kCannotOpen,   ///< the file does not exist or cannot be read
        kBadHeader,    ///< PCD/PLY header malformed, or required fields x y z missing
        kUnsupported,  ///< a valid file using a feature these readers do not handle
        kTruncated,    ///< fewer bytes/lines than the header (or the record size) promises
        kBadData,      ///< data present but not parseable (e.g. a non-number in ASCII data)
    };
    Status status = Status::kOk;  ///< how reading ended
    PointCloud cloud;             ///< finite points in the file's frame (empty unless kOk)
    int dropped_non_finite = 0;   ///< points skipped because a coordinate was NaN or infinite
    std::string error;            ///< "FILE[:LINE]: what was wrong" (empty when kOk)

    /// True when the file was read.
    bool ok() const { return status == Status::kOk; }
};

/// Reads a KITTI Velodyne scan: float32 x y z reflectance, 16 bytes per point, little-endian.
CloudReadResult ReadKittiBin(const std::string& path);

/// Reads a PCD file (v0.5-0.7): DATA ascii, binary or binary_compressed (LZF); any FIELDS with
/// per-field SIZE/TYPE/COUNT as long as x, y, z are present; reads exactly POINTS points and
/// ignores trailing bytes (SC-A-LOAM's files carry padding after the data).
CloudReadResult ReadPcd(const std::string& path);

/// Reads the vertex x y z of a PLY file (format ascii 1.0 or binary_little_endian 1.0).
CloudReadResult ReadPly(const std::string& path);

/// Reads by extension (case-insensitive): .bin -> KITTI, .pcd -> PCD, .ply -> PLY.
CloudReadResult ReadCloud(const std::string& path);

/// Writes a PCD file with FIELDS x y z (float32), DATA binary. Returns an error text or "".
std::string WritePcdBinary(const std::string& path, const PointCloud& cloud);

/// Writes a binary_little_endian PLY file with vertex x y z (float). Returns an error text or "".
std::string WritePlyBinary(const std::string& path, const PointCloud& cloud);

/// Writes a KITTI .bin scan (reflectance 0). Returns an error text or "".
std::string WriteKittiBin(const std::string& path, const PointCloud& cloud);

}  // namespace certislam::slam
