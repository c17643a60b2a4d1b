// SC-LIO-SAM keyframe folders and KITTI odometry sequences as keyframe sources.
#include "slam/io/keyframe_sources_io.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "slam/io/cloud_io.h"

namespace certislam::slam {
namespace {

using Status = KeyframeSourceResult::Status;

KeyframeSourceResult Fail(Status status, std::string error) {
    return KeyframeSourceResult::Failure(status, std::move(error));
}

// Numbers of one line; false (with *what) when a token is not a finite number.
bool ParseNumbers(const std::string& line, std::vector<double>* values, std::string* what) {
    std::istringstream in(line);
    std::string token;
    values->clear();
    while (in >> token) {
        char* end = nullptr;
        const double v = std::strtod(token.c_str(), &end);
        if (end == token.c_str() || *end != '\0' || !std::isfinite(v)) {
            *what = "'" + token + "' is not a finite number";
            return false;
        }
        values->push_back(v);
    }
    return true;
}

Eigen::Isometry3d FromRow(const std::vector<double>& v, std::size_t first) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    for (int k = 0; k < 12; ++k) T.matrix()(k / 4, k % 4) = v[first + k];
    return T;
}

std::string Where(const std::string& path, int line) {
    return path + ":" + std::to_string(line) + ": ";
}

Status ReadTimes(const std::string& path, std::vector<double>* times, std::string* error) {
    std::ifstream in(path);
    if (!in) {
        *error = path + ": cannot open";
        return Status::kCannotOpen;
    }
    std::string line, what;
    std::vector<double> v;
    for (int n = 1; std::getline(in, line); ++n) {
        if (line.empty() || line[0] == '#') continue;
        if (!ParseNumbers(line, &v, &what) || v.size() != 1) {
            *error = Where(path, n) + (what.empty() ? "expected one time in seconds" : what);
            return Status::kBadTimes;
        }
        times->push_back(v[0]);
    }
    return Status::kOk;
}

Status ReadCalibrationTr(const std::string& path, Eigen::Isometry3d* Tr, std::string* error) {
    std::ifstream in(path);
    if (!in) {
        *error = path + ": cannot open";
        return Status::kCannotOpen;
    }
    std::string line, what;
    std::vector<double> v;
    for (int n = 1; std::getline(in, line); ++n) {
        if (line.rfind("Tr:", 0) != 0) continue;
        if (!ParseNumbers(line.substr(3), &v, &what) || v.size() != 12) {
            *error = Where(path, n) + (what.empty() ? "Tr needs 12 numbers" : what);
            return Status::kBadPoses;
        }
        *Tr = FromRow(v, 0);
        return Status::kOk;
    }
    *error = path + ": no 'Tr:' line (velodyne -> cam0 calibration)";
    return Status::kBadPoses;
}

// Loads the cloud of keyframe `kf` from `path` when asked; false with *result set on error.
bool LoadCloud(const std::string& path, const KeyframeSourceOptions& options, Keyframe* kf,
               KeyframeSourceResult* result) {
    if (!options.load_clouds) return true;
    CloudReadResult read = ReadCloud(path);
    if (!read.ok()) {
        *result = Fail(Status::kBadScan, read.error);
        return false;
    }
    kf->cloud = std::make_shared<const PointCloud>(std::move(read.cloud));
    return true;
}

// Appends a keyframe, numbering it; false when max_keyframes is reached.
bool Keep(Keyframe kf, int source_index, const KeyframeSourceOptions& options,
          KeyframeSourceResult* result) {
    kf.robot = options.robot;
    kf.index = static_cast<int>(result->keyframes.size());
    result->keyframes.push_back(std::move(kf));
    result->source_indices.push_back(source_index);
    return options.max_keyframes < 0 ||
           static_cast<int>(result->keyframes.size()) < options.max_keyframes;
}

std::string ScanName(int k, const char* extension) {
    char name[32];
    std::snprintf(name, sizeof name, "%06d.%s", k, extension);
    return name;
}

}  // namespace

Status ReadKittiPoses(const std::string& path, std::vector<Eigen::Isometry3d>* poses,
                      std::vector<int>* indices, std::string* error) {
    std::ifstream in(path);
    if (!in) {
        *error = path + ": cannot open";
        return Status::kCannotOpen;
    }
    std::string line, what;
    std::vector<double> v;
    for (int n = 1; std::getline(in, line); ++n) {
        if (line.empty() || line[0] == '#') continue;
        if (!ParseNumbers(line, &v, &what) || (v.size() != 12 && v.size() != 13)) {
            *error = Where(path, n) +
                     (what.empty()
                          ? "expected 12 numbers (3x4 row-major), found " + std::to_string(v.size())
                          : what);
            return Status::kBadPoses;
        }
        const bool indexed = v.size() == 13;
        poses->push_back(FromRow(v, indexed ? 1 : 0));
        indices->push_back(indexed ? static_cast<int>(v[0]) : static_cast<int>(indices->size()));
    }
    return Status::kOk;
}

KeyframeSourceResult ReadScLioSamFolder(const std::string& folder,
                                        const KeyframeSourceOptions& options) {
    namespace fs = std::filesystem;
    const std::string scans = folder + "/Scans";
    if (!fs::is_directory(scans)) return Fail(Status::kCannotOpen, scans + ": no such folder");
    std::string error;
    std::vector<Eigen::Isometry3d> poses;
    std::vector<int> indices;
    std::vector<double> times;
    Status s = ReadKittiPoses(folder + "/optimized_poses.txt", &poses, &indices, &error);
    if (s != Status::kOk) return Fail(s, error);
    s = ReadTimes(folder + "/times.txt", &times, &error);
    if (s != Status::kOk) return Fail(s, error);
    KeyframeSourceResult result;
    KeyframeSelector selector(options.selection);
    for (int k = 0; fs::exists(scans + "/" + ScanName(k, "pcd")); ++k) {
        const std::string path = scans + "/" + ScanName(k, "pcd");
        if (k >= static_cast<int>(poses.size())) {
            std::string why = folder;
            why += "/optimized_poses.txt: " + std::to_string(poses.size());
            why += " poses but scan " + path + " exists";
            return Fail(Status::kBadPoses, why);
        }
        if (k >= static_cast<int>(times.size())) {
            std::string why = folder;
            why += "/times.txt: " + std::to_string(times.size());
            why += " times but scan " + path + " exists";
            return Fail(Status::kBadTimes, why);
        }
        Keyframe kf;
        kf.T_odom_sensor = poses[k];
        kf.stamp_ns = static_cast<std::int64_t>(std::llround(times[k] * 1e9));
        if (options.select_keyframes && !selector.Accept(kf.T_odom_sensor)) continue;
        if (!LoadCloud(path, options, &kf, &result)) return result;
        if (!Keep(std::move(kf), k, options, &result)) break;
    }
    if (result.keyframes.empty()) {
        return Fail(Status::kNoScans, scans + ": no Scans/000000.pcd (scans are numbered from 0)");
    }
    return result;
}

KeyframeSourceResult ReadKittiOdometryFolder(const std::string& folder,
                                             const std::string& poses_path,
                                             const std::string& calib_path,
                                             const KeyframeSourceOptions& options) {
    namespace fs = std::filesystem;
    const std::string velodyne = folder + "/velodyne";
    if (!fs::is_directory(velodyne)) {
        return Fail(Status::kCannotOpen, velodyne + ": no such folder");
    }
    std::string error;
    std::vector<Eigen::Isometry3d> poses;
    std::vector<int> frames;
    Eigen::Isometry3d Tr = Eigen::Isometry3d::Identity();
    Status s = ReadKittiPoses(poses_path, &poses, &frames, &error);
    if (s == Status::kOk) s = ReadCalibrationTr(calib_path, &Tr, &error);
    if (s != Status::kOk) return Fail(s, error);
    std::vector<double> times;
    if (fs::exists(folder + "/times.txt")) {
        s = ReadTimes(folder + "/times.txt", &times, &error);
        if (s != Status::kOk) return Fail(s, error);
    }
    KeyframeSourceResult result;
    KeyframeSelector selector(options.selection);
    for (size_t p = 0; p < poses.size(); ++p) {
        const int frame = frames[p];
        const std::string path = velodyne + "/" + ScanName(frame, "bin");
        if (!fs::exists(path)) {
            std::string why = path;
            why += ": missing scan for pose line of frame " + std::to_string(frame);
            why += " in " + poses_path;
            return Fail(Status::kCannotOpen, why);
        }
        Keyframe kf;
        kf.T_odom_sensor = poses[p] * Tr;  // T_world_velo = T_world_cam0 * Tr
        const double t = frame < static_cast<int>(times.size()) ? times[frame] : 0.1 * frame;
        kf.stamp_ns = static_cast<std::int64_t>(std::llround(t * 1e9));
        if (options.select_keyframes && !selector.Accept(kf.T_odom_sensor)) continue;
        if (!LoadCloud(path, options, &kf, &result)) return result;
        if (!Keep(std::move(kf), frame, options, &result)) break;
    }
    if (result.keyframes.empty()) return Fail(Status::kNoScans, poses_path + ": no poses");
    return result;
}

}  // namespace certislam::slam
