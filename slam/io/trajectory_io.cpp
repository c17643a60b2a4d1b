// TUM and KITTI trajectory files: line-by-line parsing with file:line errors.
#include "slam/io/trajectory_io.h"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <vector>

namespace certislam::slam {
namespace {

/// How far a KITTI rotation block may be from orthonormal before the line is rejected.
constexpr double kRotationTolerance = 1e-3;

std::string Where(const std::string& path, int line) {
    return path + ":" + std::to_string(line) + ": ";
}

/// Most numbers on a line of either format (KITTI: 12); parsing stops past it.
constexpr std::size_t kMaxNumbers = 12;

/// Splits a line into numbers; false with a reason when a token is not a finite number or the
/// line has more than kMaxNumbers.
bool ParseNumbers(const std::string& line, std::vector<double>* values, std::string* why) {
    std::istringstream in(line);
    std::string token;
    values->clear();
    while (in >> token) {
        if (values->size() == kMaxNumbers) {
            *why = "more than " + std::to_string(kMaxNumbers) + " numbers on the line";
            return false;
        }
        char* end = nullptr;
        const double v = std::strtod(token.c_str(), &end);
        if (end == token.c_str() || *end != '\0') {
            *why = "not a number: '" + token + "'";
            return false;
        }
        if (!std::isfinite(v)) {
            *why = "non-finite value '" + token + "'";
            return false;
        }
        values->push_back(v);
    }
    return true;
}

bool TumPose(const std::vector<double>& v, StampedPose* pose, std::string* why) {
    if (v.size() != 8) {
        *why = "expected 8 numbers (stamp tx ty tz qx qy qz qw), got " + std::to_string(v.size());
        return false;
    }
    Eigen::Quaterniond q(v[7], v[4], v[5], v[6]);
    if (q.norm() < 1e-9) {
        *why = "zero quaternion";
        return false;
    }
    q.normalize();
    pose->stamp_s = v[0];
    pose->T_world_body = Eigen::Isometry3d::Identity();
    pose->T_world_body.linear() = q.toRotationMatrix();
    pose->T_world_body.translation() = Eigen::Vector3d(v[1], v[2], v[3]);
    return true;
}

bool KittiPose(const std::vector<double>& v, int frame, StampedPose* pose, std::string* why) {
    if (v.size() != 12) {
        *why = "expected 12 numbers (3x4 [R t] row-major), got " + std::to_string(v.size());
        return false;
    }
    Eigen::Matrix3d R;
    Eigen::Vector3d t;
    for (std::size_t r = 0; r < 3; ++r) {
        const auto row = static_cast<Eigen::Index>(r);
        for (std::size_t c = 0; c < 3; ++c) R(row, static_cast<Eigen::Index>(c)) = v[4 * r + c];
        t(row) = v[4 * r + 3];
    }
    const double off = (R.transpose() * R - Eigen::Matrix3d::Identity()).norm();
    if (off > kRotationTolerance || R.determinant() < 0.0) {
        *why = "rotation block is not in SO(3) (||R^T R - I|| = " + std::to_string(off) + ")";
        return false;
    }
    pose->stamp_s = frame;
    pose->T_world_body = Eigen::Isometry3d::Identity();
    pose->T_world_body.linear() = R;
    pose->T_world_body.translation() = t;
    return true;
}

}  // namespace

bool ParseTrajectoryFormat(const std::string& name, TrajectoryFormat* format) {
    if (name == "tum") {
        *format = TrajectoryFormat::kTum;
        return true;
    }
    if (name == "kitti") {
        *format = TrajectoryFormat::kKitti;
        return true;
    }
    return false;
}

TrajectoryReadResult ReadTrajectory(const std::string& path, TrajectoryFormat format) {
    TrajectoryReadResult result;
    std::ifstream in(path);
    if (!in) {
        result.status = TrajectoryReadResult::Status::kCannotOpen;
        result.error = path + ": cannot open";
        return result;
    }
    std::string line;
    std::vector<double> values;
    int line_number = 0;
    while (std::getline(in, line)) {
        ++line_number;
        const auto first = line.find_first_not_of(" \t\r");
        if (first == std::string::npos || line[first] == '#') continue;
        std::string why;
        StampedPose pose;
        bool ok = ParseNumbers(line, &values, &why);
        if (ok && format == TrajectoryFormat::kTum) ok = TumPose(values, &pose, &why);
        if (ok && format == TrajectoryFormat::kKitti) {
            ok = KittiPose(values, static_cast<int>(result.trajectory.size()), &pose, &why);
        }
        if (!ok) {
            result.status = TrajectoryReadResult::Status::kParseError;
            result.error = Where(path, line_number) + why;
            result.trajectory.clear();
            return result;
        }
        result.trajectory.push_back(pose);
    }
    if (result.trajectory.empty()) {
        result.status = TrajectoryReadResult::Status::kParseError;
        result.error = Where(path, line_number) + "no poses in file";
    }
    return result;
}

bool WriteTrajectory(const std::string& path, const Trajectory& trajectory, TrajectoryFormat format,
                     std::string* error) {
    std::FILE* out = std::fopen(path.c_str(), "w");
    if (out == nullptr) {
        *error = path + ": cannot open for writing";
        return false;
    }
    for (const auto& pose : trajectory) {
        const Eigen::Matrix3d R = pose.T_world_body.linear();
        const Eigen::Vector3d t = pose.T_world_body.translation();
        if (format == TrajectoryFormat::kTum) {
            const Eigen::Quaterniond q(R);
            std::fprintf(out, "%.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g\n", pose.stamp_s,
                         t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w());
        } else {
            for (int r = 0; r < 3; ++r) {
                std::fprintf(out, "%.17g %.17g %.17g %.17g%s", R(r, 0), R(r, 1), R(r, 2), t(r),
                             r < 2 ? " " : "\n");
            }
        }
    }
    const bool ok = std::fclose(out) == 0;
    if (!ok) *error = path + ": write failed";
    return ok;
}

}  // namespace certislam::slam
