// Reading and writing trajectories in the TUM and KITTI text formats (as evo reads them).
#pragma once

#include <string>

#include "slam/core/trajectory.h"

namespace certislam::slam {

/// The text formats: TUM `stamp tx ty tz qx qy qz qw` per line (`#` comments), KITTI 12 numbers
/// per line (the 3x4 matrix [R t] row-major; the stamp is the line's frame index).
enum class TrajectoryFormat { kTum, kKitti };

/// What reading a trajectory file gave.
struct TrajectoryReadResult {
    enum class Status { kOk, kCannotOpen, kParseError };
    Status status = Status::kOk;  ///< kOk, or why not
    Trajectory trajectory;        ///< the poses (empty unless kOk)
    std::string error;            ///< "file:line: what was wrong" when not kOk
};

/// Parses "tum" or "kitti"; false for anything else.
bool ParseTrajectoryFormat(const std::string& name, TrajectoryFormat* format);

/// Reads a trajectory. Rejects, naming file and line: too few or too many numbers, non-numeric
/// tokens, non-finite values, a zero quaternion (TUM), a rotation block far from SO(3) (KITTI),
/// and an empty file. Quaternions are normalised (as evo does).
TrajectoryReadResult ReadTrajectory(const std::string& path, TrajectoryFormat format);

/// Writes a trajectory (17 significant digits). Returns false and sets `error` on I/O failure.
bool WriteTrajectory(const std::string& path, const Trajectory& trajectory, TrajectoryFormat format,
                     std::string* error);

}  // namespace certislam::slam
