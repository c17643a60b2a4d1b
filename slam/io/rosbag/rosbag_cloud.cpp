// sensor_msgs/PointCloud2 <-> float32 xyz clouds, checking the declared layout against the data.
#include "slam/io/rosbag/rosbag_cloud.h"

#include <array>
#include <cstring>

namespace certislam::slam {
namespace {

const char* TypeName(std::uint8_t datatype) {
    static constexpr std::array<const char*, 9> kNames = {
        "unknown", "INT8", "UINT8", "INT16", "UINT16", "INT32", "UINT32", "FLOAT32", "FLOAT64"};
    return datatype < kNames.size() ? kNames[datatype] : "unknown";
}

// Offset of float32 field `name`, or -1 with the reason in *error.
long FieldOffset(const sensor_msgs::PointCloud2& msg, const char* name, std::string* error) {
    for (const sensor_msgs::PointField& f : msg.fields) {
        if (f.name != name) continue;
        if (f.datatype != sensor_msgs::PointField::FLOAT32 || f.count != 1) {
            *error = std::string("field '") + name + "' is " + TypeName(f.datatype) + " x" +
                     std::to_string(f.count) + ", need FLOAT32 x1";
            return -1;
        }
        if (static_cast<std::uint64_t>(f.offset) + 4 > msg.point_step) {
            *error = std::string("field '") + name + "' at offset " + std::to_string(f.offset) +
                     " lies outside point_step " + std::to_string(msg.point_step);
            return -1;
        }
        return static_cast<long>(f.offset);
    }
    *error = std::string("no field '") + name + "'";
    return -1;
}

}  // namespace

bool DecodePointCloud2(const sensor_msgs::PointCloud2& msg, PointCloud* cloud, std::string* error) {
    cloud->clear();
    if (msg.is_bigendian) {
        *error = "is_bigendian is true: only little-endian clouds are read";
        return false;
    }
    const std::array<long, 3> offset = {FieldOffset(msg, "x", error), FieldOffset(msg, "y", error),
                                        FieldOffset(msg, "z", error)};
    if (offset[0] < 0 || offset[1] < 0 || offset[2] < 0) return false;
    const std::uint64_t width = msg.width, height = msg.height, step = msg.point_step;
    if (width > 0 && height > 0) {
        if (msg.row_step < width * step) {
            *error = "row_step " + std::to_string(msg.row_step) + " < width " +
                     std::to_string(width) + " x point_step " + std::to_string(step);
            return false;
        }
        const std::uint64_t need = (height - 1) * msg.row_step + width * step;
        if (msg.data.size() < need) {
            *error = "data has " + std::to_string(msg.data.size()) + " bytes, layout needs " +
                     std::to_string(need) + " (truncated)";
            return false;
        }
    }
    cloud->reserve(width * height);
    for (std::uint64_t r = 0; r < height; ++r) {
        const std::uint8_t* row = msg.data.data() + r * msg.row_step;
        for (std::uint64_t c = 0; c < width; ++c) {
            const std::uint8_t* point = row + c * step;
            Eigen::Vector3f p;
            for (int k = 0; k < 3; ++k) std::memcpy(&p[k], point + offset[k], sizeof(float));
            if (p.allFinite()) cloud->push_back(p);
        }
    }
    return true;
}

sensor_msgs::PointCloud2 EncodePointCloud2(const PointCloud& cloud, const std::string& frame_id,
                                           std::int64_t stamp_ns) {
    sensor_msgs::PointCloud2 msg;
    msg.header.frame_id = frame_id;
    msg.header.stamp.fromNSec(static_cast<std::uint64_t>(stamp_ns));
    msg.height = 1;
    msg.width = static_cast<std::uint32_t>(cloud.size());
    const char* names[3] = {"x", "y", "z"};
    for (std::uint32_t k = 0; k < 3; ++k) {
        sensor_msgs::PointField f;
        f.name = names[k];
        f.offset = 4 * k;
        f.datatype = sensor_msgs::PointField::FLOAT32;
        f.count = 1;
        msg.fields.push_back(f);
    }
    msg.is_bigendian = false;
    msg.point_step = 12;
    msg.row_step = msg.point_step * msg.width;
    msg.is_dense = true;
    msg.data.resize(static_cast<std::size_t>(msg.row_step));
    for (std::size_t i = 0; i < cloud.size(); ++i) {
        std::memcpy(msg.data.data() + 12 * i, cloud[i].data(), 12);  // float32 x, y, z
    }
    return msg;
}

}  // namespace certislam::slam
