// Files the demo writes besides trajectories, the graph and the mesh (slam/mapping/mesh_io.h):
// the SVG plot, and the progress bar it draws on stderr.
#pragma once

#include <string>
#include <vector>

#include "slam/core/trajectory.h"

namespace certislam::bin {

/// One polyline of the plot: a robot's trajectory by one method.
struct PlotSeries {
    std::string label;                     ///< legend text
    std::string colour;                    ///< SVG colour, e.g. "#1f77b4"
    bool dashed = false;                   ///< dashed stroke (ground truth)
    std::vector<slam::Trajectory> robots;  ///< one polyline per robot (x-y of each pose)
};

/// Writes a top-down (x-y) SVG of the series with a legend and a metre scale bar. Returns false
/// and sets *error when the file cannot be written.
bool WriteTrajectorySvg(const std::string& path, const std::string& title,
                        const std::vector<PlotSeries>& series, std::string* error);

/// A one-line progress bar on stderr ("\r[#####.....]  50% stage"), finished by Done().
class ProgressBar {
  public:
    /// `enabled` false draws nothing (e.g. stderr is not a terminal and quiet was asked).
    explicit ProgressBar(bool enabled) : enabled_(enabled) {}
    /// Redraws the bar at `fraction` in [0, 1] with the stage's name.
    void Update(const std::string& stage, double fraction);
    /// Ends the line.
    void Done();

  private:
    bool enabled_;
    int last_percent_ = -1;
    std::string last_stage_;
};

}  // namespace certislam::bin
