// Point-cloud files (KITTI .bin, PCD, PLY): the KITTI reader, dispatch by extension, the writers;
// the PCD and PLY readers are in cloud_io_pcd.h and cloud_io_ply.h. Errors name file and fault.
#pragma once

#include <string>

#include "slam/core/keyframe.h"
#include "slam/io/cloud_io_pcd.h"
#include "slam/io/cloud_io_ply.h"
#include "slam/io/cloud_read_result.h"

namespace certislam::slam {

/// Reads a KITTI Velodyne scan: float32 x y z reflectance, 16 bytes per point, little-endian.
CloudReadResult ReadKittiBin(const std::string& path);

/// Reads by extension (case-insensitive): .bin -> KITTI, .pcd -> PCD, .ply -> PLY.
CloudReadResult ReadCloud(const std::string& path);

/// Writes a PCD file with FIELDS x y z (float32), DATA binary. Returns an error text or "".
std::string WritePcdBinary(const std::string& path, const PointCloud& cloud);

/// Writes a binary_little_endian PLY file with vertex x y z (float). Returns an error text or "".
std::string WritePlyBinary(const std::string& path, const PointCloud& cloud);

/// Writes a KITTI .bin scan (reflectance 0). Returns an error text or "".
std::string WriteKittiBin(const std::string& path, const PointCloud& cloud);

}  // namespace certislam::slam
