// Writing keyframes as a LIO-SAM-like ROS 1 bag (test fixtures, exporting simulated missions).
#include <nav_msgs/Odometry.h>
#include <rosbag/bag.h>

#include <algorithm>

#include "slam/io/rosbag/rosbag_cloud.h"
#include "slam/io/rosbag/rosbag_source_io.h"

namespace certislam::slam {
namespace {

nav_msgs::Odometry ToOdometry(const Keyframe& kf) {
    nav_msgs::Odometry odom;
    odom.header.frame_id = "odom";
    odom.header.stamp.fromNSec(static_cast<std::uint64_t>(kf.stamp_ns));
    odom.child_frame_id = "base_link";
    const Eigen::Quaterniond q(kf.T_odom_sensor.linear());
    const Eigen::Vector3d t = kf.T_odom_sensor.translation();
    odom.pose.pose.position.x = t.x();
    odom.pose.pose.position.y = t.y();
    odom.pose.pose.position.z = t.z();
    odom.pose.pose.orientation.w = q.w();
    odom.pose.pose.orientation.x = q.x();
    odom.pose.pose.orientation.y = q.y();
    odom.pose.pose.orientation.z = q.z();
    return odom;
}

}  // namespace

bool WriteRosbagKeyframes(const std::string& path, const std::vector<Keyframe>& keyframes,
                          const RosbagSourceConfig& config, std::string* error) {
    config.Validate();
    const bool in_odom = config.cloud_frame == RosbagCloudFrame::kOdom;
    try {
        rosbag::Bag bag(path, rosbag::bagmode::Write);
        for (const Keyframe& kf : keyframes) {
            if (kf.stamp_ns < 0) {
                *error = path + ": keyframe " + std::to_string(kf.index) + " has stamp " +
                         std::to_string(kf.stamp_ns) + " ns < 0";
                return false;
            }
            // rosbag refuses record times below ros::TIME_MIN (1 ns).
            ros::Time time;
            time.fromNSec(static_cast<std::uint64_t>(std::max<std::int64_t>(kf.stamp_ns, 1)));
            bag.write(config.odometry_topic, time, ToOdometry(kf));
            PointCloud cloud = kf.cloud ? *kf.cloud : PointCloud{};
            if (in_odom) {
                const Eigen::Isometry3f T = kf.T_odom_sensor.cast<float>();
                for (Eigen::Vector3f& p : cloud) p = T * p;
            }
            bag.write(config.cloud_topic, time,
                      EncodePointCloud2(cloud, in_odom ? "odom" : "base_link", kf.stamp_ns));
        }
        bag.close();
    } catch (const std::exception& e) {
        *error = path + ": cannot write the bag: " + e.what();
        return false;
    }
    return true;
}

}  // namespace certislam::slam
