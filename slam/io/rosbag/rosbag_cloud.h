// Conversions between sensor_msgs/PointCloud2 messages and float32 xyz point clouds.
#pragma once

#include <sensor_msgs/PointCloud2.h>

#include <string>

#include "slam/core/keyframe.h"

namespace certislam::slam {

/// Reads the float32 x, y, z fields of `msg` (any point_step, row_step and offsets; height >= 1)
/// into `cloud`, dropping non-finite points. False with the reason in `error` when a field is
/// missing, not FLOAT32 with count 1, outside the point, the data is big-endian, or the data
/// is shorter than the declared layout.
bool DecodePointCloud2(const sensor_msgs::PointCloud2& msg, PointCloud* cloud, std::string* error);

/// A dense, unorganised (height 1) little-endian PointCloud2 of `cloud`: fields x, y, z float32,
/// point_step 12, in `frame_id`, stamped `stamp_ns`.
sensor_msgs::PointCloud2 EncodePointCloud2(const PointCloud& cloud, const std::string& frame_id,
                                           std::int64_t stamp_ns);

}  // namespace certislam::slam
