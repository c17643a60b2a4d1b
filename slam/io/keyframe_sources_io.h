// Keyframe sources on disk: SC-LIO-SAM / SC-A-LOAM keyframe folders (Scans/*.pcd +
// optimized_poses.txt + times.txt) and KITTI odometry sequences (velodyne/*.bin + poses +
// calibration), with errors that name the file, the line and what was wrong.
#pragma once

#include <Eigen/Geometry>
#include <string>
#include <utility>
#include <vector>

#include "slam/core/keyframe.h"
#include "slam/core/keyframe_selection.h"

namespace certislam::slam {

/// How a keyframe source was read.
struct KeyframeSourceResult {
    enum class Status {
        kOk,            ///< `keyframes` holds them
        kCannotOpen,    ///< a folder or file is missing or unreadable
        kBadPoses,      ///< a poses/calibration line is malformed (not 12 numbers, non-finite)
        kBadTimes,      ///< a times line is malformed, or times are fewer than keyframes
        kBadScan,       ///< a scan file is corrupt or truncated
        kNoScans,       ///< no scan files in the folder
        kBadBag,        ///< a ROS bag is not a bag, corrupt or truncated
        kMissingTopic,  ///< a ROS bag lacks a topic (or its type differs, or nothing paired)
    };
    Status status = Status::kOk;      ///< verdict
    std::vector<Keyframe> keyframes;  ///< index 0.., in time order (empty unless kOk)
    std::vector<int> source_indices;  ///< per keyframe: the scan/frame number it came from
    std::string error;                ///< "FILE[:LINE]: what was wrong" (empty when kOk)

    /// True when the source was read.
    bool ok() const { return status == Status::kOk; }

    /// A failed read with `status` and "FILE[:LINE]: what was wrong".
    static KeyframeSourceResult Failure(Status status, std::string error) {
        KeyframeSourceResult r;
        r.status = status;
        r.error = std::move(error);
        return r;
    }
};

/// Options shared by the folder readers.
struct KeyframeSourceOptions {
    int robot = 0;                      ///< robot id written into the keyframes
    int max_keyframes = -1;             ///< stop after this many (-1: all)
    bool load_clouds = true;            ///< false: poses and stamps only (cloud stays null)
    bool select_keyframes = false;      ///< apply `selection` (KITTI frames are not keyframes)
    KeyframeSelectionConfig selection;  ///< LIO-SAM's 1 m / 0.2 rad
};

/// Reads KITTI-format poses (one 3x4 row-major matrix per line; a leading frame index making 13
/// numbers and '#' comment lines are accepted). `indices` gets each line's frame number (its
/// line order when there is no index).
KeyframeSourceResult::Status ReadKittiPoses(const std::string& path,
                                            std::vector<Eigen::Isometry3d>* poses,
                                            std::vector<int>* indices, std::string* error);

/// A SC-LIO-SAM / SC-A-LOAM keyframe folder: Scans/NNNNNN.pcd for k = 0, 1, ... (consecutive),
/// optimized_poses.txt line k+1 = T_world_scan of scan k, times.txt line k+1 = UNIX seconds.
KeyframeSourceResult ReadScLioSamFolder(const std::string& folder,
                                        const KeyframeSourceOptions& options = {});

/// A KITTI odometry sequence: `folder`/velodyne/NNNNNN.bin, poses file (T_world_cam0 per frame,
/// or with frame indices), calibration file with a "Tr:" line (velodyne -> cam0), optional
/// `folder`/times.txt (seconds; else 0.1 s per frame). Poses become T_world_velo = P * Tr.
KeyframeSourceResult ReadKittiOdometryFolder(const std::string& folder,
                                             const std::string& poses_path,
                                             const std::string& calib_path,
                                             const KeyframeSourceOptions& options = {});

}  // namespace certislam::slam
