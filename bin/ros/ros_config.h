// The "ros" object of a team configuration: the topics and frames of `certislam_node`, the live
// ingest's pairing, selection and queue, and how often it publishes.
#pragma once

#include <string>

#include "actors/ros/live_keyframes.h"
#include "actors/ros/ros_bridge.h"
#include "bin/config/team_config.h"

namespace certislam::bin {

/// Settings of one robot's ROS node.
struct RosNodeConfig {
    actors::RosBridgeConfig bridge;   ///< topics and frames
    actors::LiveIngestConfig ingest;  ///< pairing, selection, queue
    double publish_period_s = 0.25;   ///< path, TF, status and loops this often, > 0
    double mesh_period_s = 5.0;       ///< the mesh this often (with mapping on); 0: never
    double silence_warning_s = 2.0;   ///< status says "LIO-SAM silent" after this, > 0
};

/// Reads the optional "ros" object of the configuration file `team.path` for robot `robot`:
/// cloud_topic, odometry_topic, namespace, map_frame, odom_frame ("{robot}" is replaced by the
/// id), max_stamp_gap_s, cloud_frame (auto | sensor | odom), select_keyframes,
/// min_translation_m, min_rotation_rad, queue_capacity, end_after_silence_s, publish_period_s,
/// mesh_period_s, silence_warning_s. Topics and pairing default to the source's when it is a
/// rosbag source. Throws std::runtime_error naming the file and "ros.<field>".
RosNodeConfig LoadRosNodeConfig(const TeamConfig& team, int robot);

}  // namespace certislam::bin
