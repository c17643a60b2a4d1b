// The outcome of reading a point-cloud file, shared by the KITTI, PCD and PLY readers.
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

}  // namespace certislam::slam
