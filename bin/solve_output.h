// The solution file of `certislam solve --out`: g2o, TUM or KITTI by the file's extension, in the
// input's frame (the solver's gauge is arbitrary: pose 0 is put back where the input has it).
#pragma once

#include <string>

#include "slam/core/pose_graph.h"

namespace certislam::bin {

/// "" when `path` names a format WriteSolution writes (.g2o, .tum, .kitti), else why not.
std::string SolutionFormatError(const std::string& path);

/// Moves `poses` (d x (d+1)n, blocks [R_g t_g]) rigidly so that pose 0 equals the input's
/// VERTEX estimate of pose 0 (identity when the input has none).
slam::PoseMatrix InInputFrame(const slam::PoseGraph& input, const slam::PoseMatrix& poses);

/// Writes the solution of `solved` (the graph certified) in the input's frame to `path`: .g2o
/// (vertices and edges), .tum (stamp = pose index), .kitti (3 x 4 row-major per pose); planar
/// poses are written in the z = 0 plane. False with `error` naming the file on failure.
bool WriteSolution(const std::string& path, const slam::PoseGraph& input,
                   const slam::PoseGraph& solved, const slam::PoseMatrix& poses,
                   std::string* error);

}  // namespace certislam::bin
