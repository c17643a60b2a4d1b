// The "ros" object of a team configuration.
#include "bin/ros/ros_config.h"

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <stdexcept>

namespace certislam::bin {
namespace {

using nlohmann::json;

struct Reader {
    const json& ros;
    const std::string& path;

    [[noreturn]] void Fail(const std::string& field, const std::string& rule) const {
        throw std::runtime_error(path + ": ros." + field + ": " + rule);
    }
    void Text(const char* field, int robot, std::string* value) const {
        if (!ros.contains(field)) return;
        if (!ros.at(field).is_string() || ros.at(field).get<std::string>().empty()) {
            Fail(field, "must be a non-empty string");
        }
        *value = WithRobotId(ros.at(field).get<std::string>(), robot);
    }
    void Number(const char* field, double min, double* value) const {
        if (!ros.contains(field)) return;
        if (!ros.at(field).is_number()) Fail(field, "must be a number");
        *value = ros.at(field).get<double>();
        if (!std::isfinite(*value) || *value < min) Fail(field, "must be finite, >= " + Num(min));
    }
    void Integer(const char* field, int min, int* value) const {
        if (!ros.contains(field)) return;
        if (!ros.at(field).is_number_integer()) Fail(field, "must be an integer");
        *value = ros.at(field).get<int>();
        if (*value < min) Fail(field, "must be >= " + std::to_string(min));
    }
    static std::string Num(double x) {
        std::string s = std::to_string(x);
        while (s.size() > 1 && s.back() == '0') s.pop_back();
        if (s.back() == '.') s.pop_back();
        return s;
    }
};

void ReadIngest(const Reader& r, actors::LiveIngestConfig* ingest) {
    r.Number("max_stamp_gap_s", 0.0, &ingest->max_stamp_gap_s);
    if (r.ros.contains("cloud_frame")) {
        const json& f = r.ros.at("cloud_frame");
        const std::string frame = f.is_string() ? f.get<std::string>() : "";
        if (frame == "auto") {
            ingest->cloud_frame = slam::RosbagCloudFrame::kAuto;
        } else if (frame == "sensor") {
            ingest->cloud_frame = slam::RosbagCloudFrame::kSensor;
        } else if (frame == "odom") {
            ingest->cloud_frame = slam::RosbagCloudFrame::kOdom;
        } else {
            r.Fail("cloud_frame", "must be auto, sensor or odom");
        }
    }
    if (r.ros.contains("select_keyframes")) {
        if (!r.ros.at("select_keyframes").is_boolean()) r.Fail("select_keyframes", "must be bool");
        ingest->select_keyframes = r.ros.at("select_keyframes").get<bool>();
    }
    r.Number("min_translation_m", 0.0, &ingest->selection.min_translation_m);
    r.Number("min_rotation_rad", 0.0, &ingest->selection.min_rotation_rad);
    r.Integer("queue_capacity", 1, &ingest->queue_capacity);
    r.Number("end_after_silence_s", 0.0, &ingest->end_after_silence_s);
}

}  // namespace

RosNodeConfig LoadRosNodeConfig(const TeamConfig& team, int robot) {
    RosNodeConfig config;
    config.bridge.output_namespace = "/certislam/robot" + std::to_string(robot);
    config.bridge.odom_frame = "robot" + std::to_string(robot) + "/odom";
    if (team.source.kind == SourceConfig::Kind::kRosbag) {
        config.bridge.cloud_topic = WithRobotId(team.source.rosbag.cloud_topic, robot);
        config.bridge.odometry_topic = WithRobotId(team.source.rosbag.odometry_topic, robot);
        config.ingest.max_stamp_gap_s = team.source.rosbag.max_stamp_gap_s;
        config.ingest.cloud_frame = team.source.rosbag.cloud_frame;
    }
    std::ifstream in(team.path);
    if (!in) throw std::runtime_error(team.path + ": cannot open");
    json j;
    try {
        j = json::parse(in);
    } catch (const json::exception& e) {
        throw std::runtime_error(team.path + ": " + e.what());
    }
    if (!j.contains("ros")) return config;
    if (!j.at("ros").is_object()) throw std::runtime_error(team.path + ": ros: must be an object");
    const Reader r{j.at("ros"), team.path};
    r.Text("cloud_topic", robot, &config.bridge.cloud_topic);
    r.Text("odometry_topic", robot, &config.bridge.odometry_topic);
    r.Text("namespace", robot, &config.bridge.output_namespace);
    r.Text("map_frame", robot, &config.bridge.map_frame);
    r.Text("odom_frame", robot, &config.bridge.odom_frame);
    ReadIngest(r, &config.ingest);
    r.Number("publish_period_s", 0.01, &config.publish_period_s);
    r.Number("mesh_period_s", 0.0, &config.mesh_period_s);
    r.Number("silence_warning_s", 0.01, &config.silence_warning_s);
    try {
        config.ingest.Validate();
    } catch (const std::invalid_argument& e) {
        throw std::runtime_error(team.path + ": ros: " + e.what());
    }
    return config;
}

}  // namespace certislam::bin
