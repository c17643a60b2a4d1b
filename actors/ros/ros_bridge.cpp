// ROS 1 subscriptions and publications of a robot's node (C++17: ROS 1 message headers).
#include "actors/ros/ros_bridge.h"

#include <geometry_msgs/TransformStamped.h>
#include <nav_msgs/Odometry.h>
#include <nav_msgs/Path.h>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_msgs/String.h>
#include <tf2_ros/transform_broadcaster.h>
#include <visualization_msgs/Marker.h>

#include <mutex>
#include <stdexcept>

#include "slam/io/rosbag/rosbag_cloud.h"

namespace certislam::actors {
namespace {

geometry_msgs::Pose ToPose(const Eigen::Isometry3d& T) {
    geometry_msgs::Pose p;
    const Eigen::Quaterniond q(T.linear());
    p.position.x = T.translation().x();
    p.position.y = T.translation().y();
    p.position.z = T.translation().z();
    p.orientation.w = q.w();
    p.orientation.x = q.x();
    p.orientation.y = q.y();
    p.orientation.z = q.z();
    return p;
}

geometry_msgs::Point ToPoint(const Eigen::Vector3d& x) {
    geometry_msgs::Point p;
    p.x = x.x();
    p.y = x.y();
    p.z = x.z();
    return p;
}

}  // namespace

struct RosBridge::Impl {
    RosBridgeConfig config;
    CloudCallback on_cloud;
    OdometryCallback on_odometry;
    ros::NodeHandle nh;
    ros::Subscriber cloud_sub, odom_sub;
    ros::Publisher path_pub, status_pub, loops_pub, mesh_pub;
    tf2_ros::TransformBroadcaster tf;
    ros::AsyncSpinner spinner{1};
    mutable std::mutex mutex;
    std::string last_error;

    void OnCloud(const sensor_msgs::PointCloud2::ConstPtr& msg) {
        slam::PointCloud cloud;
        std::string why;
        if (!slam::DecodePointCloud2(*msg, &cloud, &why)) {
            std::lock_guard<std::mutex> lock(mutex);
            last_error = config.cloud_topic + ": " + why;
            ROS_WARN_THROTTLE(5.0, "certislam: cloud on %s not read: %s",
                              config.cloud_topic.c_str(), why.c_str());
            return;
        }
        on_cloud(static_cast<std::int64_t>(msg->header.stamp.toNSec()), msg->header.frame_id,
                 std::move(cloud));
    }

    void OnOdometry(const nav_msgs::Odometry::ConstPtr& msg) {
        const auto& p = msg->pose.pose;
        Eigen::Quaterniond q(p.orientation.w, p.orientation.x, p.orientation.y, p.orientation.z);
        const Eigen::Vector3d t(p.position.x, p.position.y, p.position.z);
        if (!t.allFinite() || !q.coeffs().allFinite() || q.norm() < 0.5) {
            std::lock_guard<std::mutex> lock(mutex);
            last_error = config.odometry_topic + ": non-finite position or degenerate quaternion";
            return;
        }
        Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
        T.linear() = q.normalized().toRotationMatrix();
        T.translation() = t;
        on_odometry(static_cast<std::int64_t>(msg->header.stamp.toNSec()), msg->header.frame_id, T);
    }

    visualization_msgs::Marker Marker(int type, const char* ns) const {
        visualization_msgs::Marker m;
        m.header.frame_id = config.map_frame;
        m.header.stamp = ros::Time::now();
        m.ns = ns;
        m.id = 0;
        m.type = type;
        m.action = visualization_msgs::Marker::ADD;
        m.pose.orientation.w = 1.0;
        m.scale.x = m.scale.y = m.scale.z = 1.0;
        m.color.a = 1.0f;
        return m;
    }
};

void RosBridge::Init(int* argc, char** argv, const std::string& name) {
    ros::init(*argc, argv, name, ros::init_options::NoSigintHandler);
}

RosBridge::RosBridge(const RosBridgeConfig& config, CloudCallback on_cloud,
                     OdometryCallback on_odometry) {
    // A master started just before the node may take a few seconds to answer.
    const ros::WallTime give_up = ros::WallTime::now() + ros::WallDuration(15.0);
    while (!ros::master::check() && ros::WallTime::now() < give_up) {
        ros::WallDuration(0.2).sleep();
    }
    if (!ros::master::check()) {
        throw std::runtime_error("no ROS master at " + ros::master::getURI() +
                                 " (start roscore or set ROS_MASTER_URI)");
    }
    impl_ = std::make_unique<Impl>();
    impl_->config = config;
    impl_->on_cloud = std::move(on_cloud);
    impl_->on_odometry = std::move(on_odometry);
    ros::NodeHandle& nh = impl_->nh;
    const std::string& ns = config.output_namespace;
    impl_->path_pub = nh.advertise<nav_msgs::Path>(ns + "/path", 1, true);
    impl_->status_pub = nh.advertise<std_msgs::String>(ns + "/status", 10, true);
    impl_->loops_pub = nh.advertise<visualization_msgs::Marker>(ns + "/loops", 1, true);
    impl_->mesh_pub = nh.advertise<visualization_msgs::Marker>(ns + "/mesh", 1, true);
    const auto queue = static_cast<std::uint32_t>(config.subscriber_queue);
    impl_->cloud_sub = nh.subscribe(config.cloud_topic, queue, &Impl::OnCloud, impl_.get());
    impl_->odom_sub = nh.subscribe(config.odometry_topic, queue, &Impl::OnOdometry, impl_.get());
    impl_->spinner.start();
}

RosBridge::~RosBridge() {
    StopSubscriptions();
    impl_->spinner.stop();
}

void RosBridge::StopSubscriptions() {
    impl_->cloud_sub.shutdown();
    impl_->odom_sub.shutdown();
}

bool RosBridge::Ok() const { return ros::ok(); }

std::int64_t RosBridge::NowNs() const {
    return static_cast<std::int64_t>(ros::Time::now().toNSec());
}

std::string RosBridge::LastError() const {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    return impl_->last_error;
}

void RosBridge::PublishPath(const slam::Trajectory& trajectory) {
    nav_msgs::Path path;
    path.header.frame_id = impl_->config.map_frame;
    path.header.stamp = ros::Time::now();
    path.poses.reserve(trajectory.size());
    for (const slam::StampedPose& sp : trajectory) {
        geometry_msgs::PoseStamped ps;
        ps.header.frame_id = impl_->config.map_frame;
        ps.header.stamp.fromSec(sp.stamp_s);
        ps.pose = ToPose(sp.T_world_body);
        path.poses.push_back(ps);
    }
    impl_->path_pub.publish(path);
}

void RosBridge::PublishTransform(const Eigen::Isometry3d& T_map_odom) {
    geometry_msgs::TransformStamped t;
    t.header.frame_id = impl_->config.map_frame;
    t.header.stamp = ros::Time::now();
    t.child_frame_id = impl_->config.odom_frame;
    const geometry_msgs::Pose p = ToPose(T_map_odom);
    t.transform.translation.x = p.position.x;
    t.transform.translation.y = p.position.y;
    t.transform.translation.z = p.position.z;
    t.transform.rotation = p.orientation;
    impl_->tf.sendTransform(t);
}

void RosBridge::PublishStatus(const std::string& json) {
    std_msgs::String s;
    s.data = json;
    impl_->status_pub.publish(s);
}

void RosBridge::PublishLoops(const std::vector<LoopSegment>& loops) {
    visualization_msgs::Marker m = impl_->Marker(visualization_msgs::Marker::LINE_LIST, "loops");
    m.scale.x = 0.3;
    m.color.r = 1.0f;
    m.color.g = 0.2f;
    for (const LoopSegment& l : loops) {
        m.points.push_back(ToPoint(l.a));
        m.points.push_back(ToPoint(l.b));
    }
    impl_->loops_pub.publish(m);
}

void RosBridge::PublishMesh(const slam::TriangleMesh& mesh) {
    visualization_msgs::Marker m = impl_->Marker(visualization_msgs::Marker::TRIANGLE_LIST, "mesh");
    m.color.r = 0.6f;
    m.color.g = 0.7f;
    m.color.b = 0.8f;
    m.points.reserve(mesh.triangles.size() * 3);
    for (const Eigen::Vector3i& tri : mesh.triangles) {
        for (int k = 0; k < 3; ++k) {
            m.points.push_back(ToPoint(mesh.vertices[static_cast<size_t>(tri[k])].cast<double>()));
        }
    }
    impl_->mesh_pub.publish(m);
}

}  // namespace certislam::actors
