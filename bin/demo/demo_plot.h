// The demo's figure: one top-down map panel per method against ground truth, and each robot's
// position error along its trajectory, as one self-contained SVG a browser opens.
#pragma once

#include <string>
#include <vector>

#include "slam/core/trajectory.h"

namespace certislam::bin {

/// One method's trajectories, already aligned to ground truth, and its per-robot RMSE.
struct DemoPlotMethod {
    std::string name;                      ///< e.g. "certified RBCD"
    std::string colour;                    ///< SVG colour of its error curves
    std::vector<slam::Trajectory> robots;  ///< [robot], aligned to the ground-truth frame
    std::vector<double> rmse;              ///< [robot] position RMSE, m
    double stroke_width = 1.6;             ///< error curve width (wide + translucent shows overlap)
};

/// Everything the figure shows.
struct DemoPlotInput {
    std::string title;                           ///< first line of the figure
    std::vector<slam::Trajectory> ground_truth;  ///< [robot]
    std::vector<DemoPlotMethod> methods;         ///< one map panel each
};

/// Writes the SVG: a grid of x-y map panels (ground truth dashed black, robots in their own
/// colours, RMSE in the panel title), then per robot the position error (m) of every method
/// against keyframe index. Returns false and sets *error when the file cannot be written.
bool WriteDemoPlot(const std::string& path, const DemoPlotInput& input, std::string* error);

}  // namespace certislam::bin
