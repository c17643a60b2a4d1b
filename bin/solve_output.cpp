// Writing `certislam solve --out` in the input's frame (see solve_output.h).
#include "bin/solve_output.h"

#include <filesystem>

#include "slam/io/g2o_io.h"
#include "slam/io/trajectory_io.h"

namespace certislam::bin {
namespace {

/// Pose g of a d x (d+1)n matrix as a homogeneous (d+1) x (d+1) transform.
Eigen::MatrixXd Homogeneous(const slam::PoseMatrix& poses, int g, int d) {
    Eigen::MatrixXd T = Eigen::MatrixXd::Identity(d + 1, d + 1);
    T.topRows(d) = poses.middleCols(slam::BlockColumn(g, d), d + 1);
    return T;
}

std::string Extension(const std::string& path) {
    return std::filesystem::path(path).extension().string();
}

}  // namespace

std::string SolutionFormatError(const std::string& path) {
    const std::string ext = Extension(path);
    if (ext == ".g2o" || ext == ".tum" || ext == ".kitti") return "";
    return path + ": unknown output format '" + ext + "' (use .g2o, .tum or .kitti)";
}

slam::PoseMatrix InInputFrame(const slam::PoseGraph& input, const slam::PoseMatrix& poses) {
    const int d = static_cast<int>(poses.rows());
    const int n = static_cast<int>(poses.cols()) / (d + 1);
    if (n == 0) return poses;
    const Eigen::MatrixXd T_input0 = input.initial_guess && input.initial_guess->rows() == d
                                         ? Homogeneous(*input.initial_guess, 0, d)
                                         : Eigen::MatrixXd::Identity(d + 1, d + 1);
    // T_fix maps the solver's frame to the input's: T_fix * T_solved0 = T_input0.
    const Eigen::MatrixXd T_fix = T_input0 * Homogeneous(poses, 0, d).inverse();
    slam::PoseMatrix out(d, poses.cols());
    for (int g = 0; g < n; ++g) {
        out.middleCols(slam::BlockColumn(g, d), d + 1) =
            (T_fix * Homogeneous(poses, g, d)).topRows(d);
    }
    return out;
}

bool WriteSolution(const std::string& path, const slam::PoseGraph& input,
                   const slam::PoseGraph& solved, const slam::PoseMatrix& poses,
                   std::string* error) {
    if (const std::string why = SolutionFormatError(path); !why.empty()) {
        *error = why;
        return false;
    }
    const slam::PoseMatrix framed = InInputFrame(input, poses);
    if (Extension(path) == ".g2o") return slam::WriteG2o(path, solved, framed, error);
    const int d = static_cast<int>(framed.rows());
    slam::Trajectory trajectory;
    for (int g = 0; g < static_cast<int>(framed.cols()) / (d + 1); ++g) {
        const Eigen::MatrixXd T = Homogeneous(framed, g, d);
        Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
        pose.linear().topLeftCorner(d, d) = T.topLeftCorner(d, d);
        pose.translation().head(d) = T.topRightCorner(d, 1);
        trajectory.push_back({static_cast<double>(g), pose});
    }
    const auto format =
        Extension(path) == ".tum" ? slam::TrajectoryFormat::kTum : slam::TrajectoryFormat::kKitti;
    return slam::WriteTrajectory(path, trajectory, format, error);
}

}  // namespace certislam::bin
