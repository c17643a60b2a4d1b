// The PLY reader: vertex x y z of ascii and binary_little_endian files.
#pragma once

#include <string>

#include "slam/io/cloud_read_result.h"

namespace certislam::slam {

/// Reads the vertex x y z of a PLY file (format ascii 1.0 or binary_little_endian 1.0).
CloudReadResult ReadPly(const std::string& path);

}  // namespace certislam::slam
