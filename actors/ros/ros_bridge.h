// The ROS 1 side of a robot node: subscribes to LIO-SAM's cloud and odometry topics and publishes
// the team's results (path, TF, status, loop markers, mesh). No ROS type in this header: ROS 1's
// message headers need C++17, the actor graph C++20 (see slam/io/rosbag/CMakeLists.txt).
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "slam/core/keyframe.h"
#include "slam/core/trajectory.h"
#include "slam/mapping/mesh.h"

namespace certislam::actors {

/// Topics and frames of one robot's node.
struct RosBridgeConfig {
    std::string cloud_topic = "/lio_sam/mapping/cloud_registered_raw";  ///< PointCloud2 in
    std::string odometry_topic = "/lio_sam/mapping/odometry";           ///< nav_msgs/Odometry in
    std::string output_namespace = "/certislam/robot0";  ///< path, status, loops, mesh under it
    std::string map_frame = "map";                       ///< the team frame
    std::string odom_frame = "robot0/odom";              ///< this robot's odometry frame
    int subscriber_queue = 100;                          ///< ROS subscriber queue length
};

/// A cloud message as points (float32 x, y, z decoded), with its header.
using CloudCallback =
    std::function<void(std::int64_t stamp_ns, const std::string& frame_id, slam::PointCloud cloud)>;
/// An odometry message's pose, with its header.
using OdometryCallback = std::function<void(std::int64_t stamp_ns, const std::string& frame_id,
                                            const Eigen::Isometry3d& T_odom_sensor)>;

/// One inter-robot loop closure drawn as a segment between its two poses (team frame).
struct LoopSegment {
    Eigen::Vector3d a = Eigen::Vector3d::Zero();  ///< one end
    Eigen::Vector3d b = Eigen::Vector3d::Zero();  ///< the other end
};

/// Subscriptions (served by a background spinner) and publishers (latched) of a robot's node.
class RosBridge {
  public:
    /// ros::init without ROS's SIGINT handler (the caller handles signals); `name` is the node's.
    static void Init(int* argc, char** argv, const std::string& name);
    /// Throws std::runtime_error when the ROS master cannot be reached within 15 s.
    RosBridge(const RosBridgeConfig& config, CloudCallback on_cloud, OdometryCallback on_odometry);
    ~RosBridge();

    /// False once ROS shuts down.
    bool Ok() const;
    /// ROS time now (the /clock with /use_sim_time), nanoseconds.
    std::int64_t NowNs() const;
    /// The last cloud that could not be decoded, as "topic: why" (empty: none).
    std::string LastError() const;
    /// Stops the subscriptions (no callback runs after it returns).
    void StopSubscriptions();

    /// nav_msgs/Path of the robot's poses in the map frame (stamps from the keyframes).
    void PublishPath(const slam::Trajectory& trajectory);
    /// TF map_frame -> odom_frame.
    void PublishTransform(const Eigen::Isometry3d& T_map_odom);
    /// std_msgs/String holding one JSON object.
    void PublishStatus(const std::string& json);
    /// LINE_LIST marker of the loop closures.
    void PublishLoops(const std::vector<LoopSegment>& loops);
    /// TRIANGLE_LIST marker of the mesh (map frame).
    void PublishMesh(const slam::TriangleMesh& mesh);

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace certislam::actors
