// The PCD reader: header, ASCII, binary and binary_compressed (LZF, decoded by PCL) point data.
#pragma once

#include <string>
#include <vector>

#include "slam/io/cloud_read_result.h"

namespace certislam::slam {

/// Reads a PCD file (v0.5-0.7): DATA ascii, binary or binary_compressed (LZF); any FIELDS with
/// per-field SIZE/TYPE/COUNT as long as x, y, z are present; reads exactly POINTS points and
/// ignores trailing bytes (SC-A-LOAM's files carry padding after the data).
CloudReadResult ReadPcd(const std::string& path);

namespace cloud_io_internal {

/// Reads a PCD file from its bytes (`path` only names it in errors).
CloudReadResult ParsePcd(const std::string& path, const std::vector<unsigned char>& bytes);

}  // namespace cloud_io_internal
}  // namespace certislam::slam
