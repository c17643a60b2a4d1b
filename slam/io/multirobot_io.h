// Reading the multi-robot pose-graph CSV (data/g2o/multirobot/tunnels/robot*/measurements.csv).
#pragma once

#include <string>

#include "slam/io/g2o_io.h"

namespace certislam::slam {

/// Reads every `robot<k>/measurements.csv` under `dir` (k = 0, 1, ... while the file exists).
/// Header: robot_src,pose_src,robot_dst,pose_dst,qx,qy,qz,qw,tx,ty,tz,kappa,tau,is_known_inlier,
/// weight. Inter-robot edges listed in both robots' files are kept once (keyed by
/// (robot_src,pose_src,robot_dst,pose_dst)). Poses (robot, index) get global indices with each
/// robot's poses contiguous (robot 0 first) and `graph.ids` names them; a robot's pose count is
/// its largest index seen + 1. `is_known_inlier` is kept; the file's `weight` column (weights of
/// an earlier GNC run) is not used: every edge gets weight 1.
PoseGraphReadResult ReadMultiRobotCsv(const std::string& dir);

}  // namespace certislam::slam
