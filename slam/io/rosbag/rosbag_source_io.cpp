// LIO-SAM bags as a keyframe source: clouds paired with odometry by stamp, errors named.
#include "slam/io/rosbag/rosbag_source_io.h"

#include <nav_msgs/Odometry.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/PointCloud2.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>
#include <optional>
#include <stdexcept>

#include "slam/io/rosbag/rosbag_cloud.h"

namespace certislam::slam {
namespace {

using Status = KeyframeSourceResult::Status;

KeyframeSourceResult Fail(Status status, std::string error) {
    return KeyframeSourceResult::Failure(status, std::move(error));
}

struct StampedPose {
    std::int64_t stamp_ns = 0;
    Eigen::Isometry3d T_odom_sensor = Eigen::Isometry3d::Identity();
    std::string frame_id;  // the odometry's header.frame_id (the odom frame)
};

// A cloud message paired with its odometry, before selection.
struct Paired {
    std::int64_t stamp_ns = 0;
    int message = 0;
    const StampedPose* pose = nullptr;
    PointCloudPtr cloud;
};

// "topic [type], ..." of every connection in the bag, for error messages.
std::string TopicList(rosbag::View& view) {
    std::map<std::string, std::string> topics;
    for (const rosbag::ConnectionInfo* c : view.getConnections()) topics[c->topic] = c->datatype;
    std::string list;
    for (const auto& [topic, type] : topics) {
        if (!list.empty()) list += ", ";
        list += topic;
        list += " [";
        list += type;
        list += "]";
    }
    return list.empty() ? "none" : list;
}

// Empty when `topic` exists with `type`; else what is wrong.
std::string CheckTopic(rosbag::View& all, const std::string& topic, const char* type) {
    for (const rosbag::ConnectionInfo* c : all.getConnections()) {
        if (c->topic != topic) continue;
        if (c->datatype == type) return {};
        return "topic '" + topic + "' is " + c->datatype + ", expected " + type;
    }
    return "no topic '" + topic + "' (topics: " + TopicList(all) + ")";
}

// Odometry poses sorted by stamp; empty optional (with *error) on a non-finite pose.
std::optional<std::vector<StampedPose>> ReadOdometry(rosbag::Bag& bag, const std::string& path,
                                                     const std::string& topic, std::string* error) {
    std::vector<StampedPose> poses;
    rosbag::View view(bag, rosbag::TopicQuery(topic));
    int n = 0;
    for (const rosbag::MessageInstance& m : view) {
        const nav_msgs::Odometry::ConstPtr odom = m.instantiate<nav_msgs::Odometry>();
        if (!odom) continue;
        const auto& p = odom->pose.pose;
        Eigen::Quaterniond q(p.orientation.w, p.orientation.x, p.orientation.y, p.orientation.z);
        const Eigen::Vector3d t(p.position.x, p.position.y, p.position.z);
        if (!t.allFinite() || !q.coeffs().allFinite() || q.norm() < 0.5) {
            *error = path;
            *error += ": odometry message " + std::to_string(n);
            *error += " on '" + topic;
            *error += "' has a non-finite position or a degenerate quaternion";
            return std::nullopt;
        }
        StampedPose sp;
        sp.stamp_ns = static_cast<std::int64_t>(odom->header.stamp.toNSec());
        sp.T_odom_sensor.linear() = q.normalized().toRotationMatrix();
        sp.T_odom_sensor.translation() = t;
        sp.frame_id = odom->header.frame_id;
        poses.push_back(std::move(sp));
        ++n;
    }
    std::stable_sort(poses.begin(), poses.end(),
                     [](const auto& a, const auto& b) { return a.stamp_ns < b.stamp_ns; });
    return poses;
}

// The pose of nearest stamp within max_gap_ns, or null.
const StampedPose* Nearest(const std::vector<StampedPose>& poses, std::int64_t stamp_ns,
                           std::int64_t max_gap_ns) {
    auto it = std::lower_bound(poses.begin(), poses.end(), stamp_ns,
                               [](const StampedPose& p, std::int64_t s) { return p.stamp_ns < s; });
    const StampedPose* best = nullptr;
    std::int64_t best_gap = max_gap_ns;
    for (auto c : {it, it == poses.begin() ? poses.end() : it - 1}) {
        if (c == poses.end()) continue;
        const std::int64_t gap = std::llabs(c->stamp_ns - stamp_ns);
        if (gap <= best_gap) {
            best_gap = gap;
            best = &*c;
        }
    }
    return best;
}

// Pairs every cloud on the topic, decoding clouds when asked; error status on a bad cloud.
Status ReadClouds(rosbag::Bag& bag, const std::string& path, const RosbagSourceConfig& config,
                  const KeyframeSourceOptions& options, const std::vector<StampedPose>& poses,
                  std::vector<Paired>* paired, std::string* error) {
    const auto max_gap_ns = static_cast<std::int64_t>(std::llround(config.max_stamp_gap_s * 1e9));
    rosbag::View view(bag, rosbag::TopicQuery(config.cloud_topic));
    int n = -1;
    for (const rosbag::MessageInstance& m : view) {
        ++n;
        const sensor_msgs::PointCloud2::ConstPtr msg = m.instantiate<sensor_msgs::PointCloud2>();
        if (!msg) continue;
        Paired p;
        p.stamp_ns = static_cast<std::int64_t>(msg->header.stamp.toNSec());
        p.message = n;
        p.pose = Nearest(poses, p.stamp_ns, max_gap_ns);
        if (p.pose == nullptr) continue;
        if (options.load_clouds) {
            const bool in_odom =
                CloudIsInOdomFrame(config.cloud_frame, msg->header.frame_id, p.pose->frame_id);
            PointCloud cloud;
            std::string why;
            if (!DecodePointCloud2(*msg, &cloud, &why)) {
                *error = path;
                *error += ": cloud message " + std::to_string(n);
                *error += " on '" + config.cloud_topic;
                *error += "': " + why;
                return Status::kBadScan;
            }
            if (in_odom) {
                const Eigen::Isometry3f T_sensor_odom =
                    p.pose->T_odom_sensor.inverse().cast<float>();
                for (Eigen::Vector3f& x : cloud) x = T_sensor_odom * x;
            }
            p.cloud = std::make_shared<const PointCloud>(std::move(cloud));
        }
        paired->push_back(std::move(p));
    }
    std::stable_sort(paired->begin(), paired->end(),
                     [](const Paired& a, const Paired& b) { return a.stamp_ns < b.stamp_ns; });
    return Status::kOk;
}

KeyframeSourceResult Select(std::vector<Paired> paired, const KeyframeSourceOptions& options) {
    KeyframeSourceResult result;
    KeyframeSelector selector(options.selection);
    for (Paired& p : paired) {
        if (options.max_keyframes >= 0 &&
            static_cast<int>(result.keyframes.size()) >= options.max_keyframes) {
            break;
        }
        if (options.select_keyframes && !selector.Accept(p.pose->T_odom_sensor)) continue;
        Keyframe kf;
        kf.robot = options.robot;
        kf.index = static_cast<int>(result.keyframes.size());
        kf.stamp_ns = p.stamp_ns;
        kf.T_odom_sensor = p.pose->T_odom_sensor;
        kf.cloud = std::move(p.cloud);
        result.keyframes.push_back(std::move(kf));
        result.source_indices.push_back(p.message);
    }
    return result;
}

KeyframeSourceResult ReadOpenBag(rosbag::Bag& bag, const std::string& path,
                                 const RosbagSourceConfig& config,
                                 const KeyframeSourceOptions& options) {
    rosbag::View all(bag);
    std::string error = CheckTopic(all, config.cloud_topic, "sensor_msgs/PointCloud2");
    if (error.empty()) error = CheckTopic(all, config.odometry_topic, "nav_msgs/Odometry");
    if (!error.empty()) return Fail(Status::kMissingTopic, path + ": " + error);
    const auto poses = ReadOdometry(bag, path, config.odometry_topic, &error);
    if (!poses) return Fail(Status::kBadPoses, error);
    std::vector<Paired> paired;
    const Status s = ReadClouds(bag, path, config, options, *poses, &paired, &error);
    if (s != Status::kOk) return Fail(s, error);
    if (paired.empty()) {
        return Fail(Status::kMissingTopic,
                    path + ": no cloud on '" + config.cloud_topic + "' has an odometry on '" +
                        config.odometry_topic + "' within " +
                        std::to_string(config.max_stamp_gap_s) + " s of its stamp");
    }
    return Select(std::move(paired), options);
}

}  // namespace

bool CloudIsInOdomFrame(RosbagCloudFrame frame, const std::string& cloud_frame_id,
                        const std::string& odom_frame_id) {
    return frame == RosbagCloudFrame::kOdom ||
           (frame == RosbagCloudFrame::kAuto && !cloud_frame_id.empty() &&
            cloud_frame_id == odom_frame_id);
}

void RosbagSourceConfig::Validate() const {
    if (cloud_topic.empty()) {
        throw std::invalid_argument("RosbagSourceConfig.cloud_topic is empty: must name a topic");
    }
    if (odometry_topic.empty()) {
        throw std::invalid_argument(
            "RosbagSourceConfig.odometry_topic is empty: must name a topic");
    }
    if (!(max_stamp_gap_s >= 0.0) || !std::isfinite(max_stamp_gap_s)) {
        throw std::invalid_argument("RosbagSourceConfig.max_stamp_gap_s = " +
                                    std::to_string(max_stamp_gap_s) + ": must be finite, >= 0");
    }
}

KeyframeSourceResult ReadRosbagKeyframes(const std::string& path, const RosbagSourceConfig& config,
                                         const KeyframeSourceOptions& options) {
    config.Validate();
    options.selection.Validate();
    if (!std::filesystem::is_regular_file(path)) {
        return Fail(Status::kCannotOpen, path + ": no such file");
    }
    // rosbag throws BagException (format, I/O) and ros::Exception (e.g. a message overrunning
    // its record in a truncated chunk); both derive from std::exception.
    try {
        rosbag::Bag bag;
        bag.open(path, rosbag::bagmode::Read);
        return ReadOpenBag(bag, path, config, options);
    } catch (const std::exception& e) {
        return Fail(Status::kBadBag,
                    path + ": not a readable ROS 1 bag (corrupt or truncated): " + e.what());
    }
}

}  // namespace certislam::slam
