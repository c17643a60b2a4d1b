// ROS 1 bags of LIO-SAM output (keyframe clouds as sensor_msgs/PointCloud2 and poses as
// nav_msgs/Odometry) as a keyframe source, read and written with Debian's ROS 1 bag libraries.
#pragma once

#include <string>
#include <vector>

#include "slam/core/keyframe.h"
#include "slam/io/keyframe_sources_io.h"

namespace certislam::slam {

/// Which frame a bag's clouds are in.
enum class RosbagCloudFrame {
    kAuto,    ///< odom frame when the cloud's frame_id equals the odometry's header.frame_id
              ///< (LIO-SAM's cloud_registered_raw), else the sensor frame (cloud_deskewed)
    kSensor,  ///< the sensor frame: points are kept as they are
    kOdom,    ///< the odometry frame: points are mapped into the sensor frame by T_odom_sensor^-1
};

/// True when a cloud in frame `cloud_frame_id` is in the odometry frame `odom_frame_id` under
/// the rule `frame` (kAuto: the frame ids are equal and not empty).
bool CloudIsInOdomFrame(RosbagCloudFrame frame, const std::string& cloud_frame_id,
                        const std::string& odom_frame_id);

/// Topics and pairing rules of a LIO-SAM bag.
struct RosbagSourceConfig {
    std::string cloud_topic = "/lio_sam/mapping/cloud_registered_raw";  ///< PointCloud2 topic
    std::string odometry_topic = "/lio_sam/mapping/odometry";           ///< nav_msgs/Odometry
    double max_stamp_gap_s = 0.01;  ///< a cloud pairs with the nearest odometry within this, >= 0
    RosbagCloudFrame cloud_frame = RosbagCloudFrame::kAuto;  ///< frame of the clouds

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// Reads keyframes from the ROS 1 bag at `path`: every cloud on `cloud_topic` paired with the
/// odometry message of the nearest header stamp (within max_stamp_gap_s; clouds with none are
/// skipped), in cloud-stamp order. Clouds need float32 x, y, z fields (any point_step and
/// offsets, little-endian); NaN points are dropped. `source_indices` holds each keyframe's
/// message number on the cloud topic. Errors (status and "FILE: what was wrong"):
/// kCannotOpen (missing file), kBadBag (not a bag, corrupt or truncated), kMissingTopic (a topic
/// absent, of another type, or no cloud paired), kBadScan (cloud layout not readable), kBadPoses
/// (non-finite pose). Validates `config` (throws std::invalid_argument).
KeyframeSourceResult ReadRosbagKeyframes(const std::string& path,
                                         const RosbagSourceConfig& config = {},
                                         const KeyframeSourceOptions& options = {});

/// Writes `keyframes` as a LIO-SAM-like bag: per keyframe one nav_msgs/Odometry (frame "odom",
/// child "base_link") and one PointCloud2 (x, y, z float32, frame "base_link", i.e. the sensor
/// frame; the odom frame when config.cloud_frame is kOdom) stamped keyframe.stamp_ns. Returns
/// false with "PATH: what was wrong" in `error` when the bag cannot be written.
bool WriteRosbagKeyframes(const std::string& path, const std::vector<Keyframe>& keyframes,
                          const RosbagSourceConfig& config, std::string* error);

}  // namespace certislam::slam
