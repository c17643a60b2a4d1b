// Hand-written SVG (polylines, text): map panels per method and error-along-trajectory panels.
#include "bin/demo/demo_plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

namespace certislam::bin {
namespace {

constexpr double kMapPanelWidthPx = 620.0;  ///< width of one map panel
constexpr double kErrorHeightPx = 190.0;    ///< height of one error panel
constexpr double kGapPx = 50.0;             ///< space between panels (titles, axes)
constexpr int kMapColumns = 2;              ///< map panels per row
const char* const kRobotColours[] = {"#1f77b4", "#d62728", "#2ca02c", "#9467bd",
                                     "#8c564b", "#e377c2", "#17becf", "#bcbd22"};

struct Box {
    double x0, y0, x1, y1;  // data extent (map: metres; error: index and metres)
};

const char* RobotColour(size_t r) { return kRobotColours[r % 8]; }

std::string Fixed(double v, int digits) {
    char buf[64];
    std::snprintf(buf, sizeof(buf), "%.*f", digits, v);
    return buf;
}

/// A polyline from data points mapped into the pixel rectangle (px, py, w, h) of `box`.
void Polyline(std::ostream& out, const std::vector<Eigen::Vector2d>& pts, const Box& box, double px,
              double py, double w, double h, const std::string& style) {
    out << "<polyline fill=\"none\" " << style << " points=\"";
    for (const auto& p : pts) {
        out << Fixed(px + (p.x() - box.x0) / (box.x1 - box.x0) * w, 1) << ","
            << Fixed(py + (box.y1 - p.y()) / (box.y1 - box.y0) * h, 1) << " ";
    }
    out << "\"/>\n";
}

std::vector<Eigen::Vector2d> Xy(const slam::Trajectory& traj) {
    std::vector<Eigen::Vector2d> pts;
    for (const auto& p : traj) pts.push_back(p.T_world_body.translation().head<2>());
    return pts;
}

Box MapExtent(const DemoPlotInput& input) {
    Box box{1e300, 1e300, -1e300, -1e300};
    for (const auto& traj : input.ground_truth) {
        for (const auto& p : Xy(traj)) {
            box = {std::min(box.x0, p.x()), std::min(box.y0, p.y()), std::max(box.x1, p.x()),
                   std::max(box.y1, p.y())};
        }
    }
    if (box.x0 > box.x1) box = {0, 0, 1, 1};
    const double margin = 0.04 * std::max({box.x1 - box.x0, box.y1 - box.y0, 1.0});
    return {box.x0 - margin, box.y0 - margin, box.x1 + margin, box.y1 + margin};
}

/// Per-keyframe position error of `est` against `gt` (matched by index; same stamps).
std::vector<Eigen::Vector2d> Errors(const slam::Trajectory& gt, const slam::Trajectory& est) {
    std::vector<Eigen::Vector2d> pts;
    for (size_t i = 0; i < std::min(gt.size(), est.size()); ++i) {
        const double e =
            (gt[i].T_world_body.translation() - est[i].T_world_body.translation()).norm();
        pts.emplace_back(static_cast<double>(i), e);
    }
    return pts;
}

void MapPanel(std::ostream& out, const DemoPlotInput& input, const DemoPlotMethod& method,
              const Box& box, double px, double py, double w, double h) {
    std::string title = method.name + ": RMSE";
    for (size_t r = 0; r < method.rmse.size(); ++r) {
        title += (r ? " / " : " ") + Fixed(method.rmse[r], 2);
    }
    out << "<text x=\"" << px << "\" y=\"" << py - 8 << "\" font-weight=\"bold\">" << title
        << " m</text>\n<rect x=\"" << px << "\" y=\"" << py << "\" width=\"" << w << "\" height=\""
        << h << "\" fill=\"none\" stroke=\"#cccccc\"/>\n";
    for (const auto& traj : input.ground_truth) {
        Polyline(out, Xy(traj), box, px, py, w, h,
                 "stroke=\"black\" stroke-width=\"1\" stroke-dasharray=\"5,3\"");
    }
    for (size_t r = 0; r < method.robots.size(); ++r) {
        Polyline(out, Xy(method.robots[r]), box, px, py, w, h,
                 std::string("stroke=\"") + RobotColour(r) + "\" stroke-width=\"1.6\"");
    }
}

void ErrorPanel(std::ostream& out, const DemoPlotInput& input, size_t robot, double px, double py,
                double w) {
    double max_error = 0.1;
    for (const auto& m : input.methods) {
        for (const auto& p : Errors(input.ground_truth[robot], m.robots[robot])) {
            max_error = std::max(max_error, p.y());
        }
    }
    const double n = std::max<double>(1.0, static_cast<double>(input.ground_truth[robot].size()));
    const Box box{0.0, 0.0, n - 1.0, max_error * 1.05};
    out << "<text x=\"" << px << "\" y=\"" << py - 8 << "\" font-weight=\"bold\" fill=\""
        << RobotColour(robot) << "\">robot " << robot
        << ": position error (m) against keyframe index</text>\n<rect x=\"" << px << "\" y=\"" << py
        << "\" width=\"" << w << "\" height=\"" << kErrorHeightPx
        << "\" fill=\"none\" stroke=\"#cccccc\"/>\n<text x=\"" << px - 4 << "\" y=\"" << py + 12
        << "\" text-anchor=\"end\">" << Fixed(box.y1, 1) << "</text>\n<text x=\"" << px - 4
        << "\" y=\"" << py + kErrorHeightPx << "\" text-anchor=\"end\">0</text>\n";
    for (const auto& m : input.methods) {
        Polyline(out, Errors(input.ground_truth[robot], m.robots[robot]), box, px, py, w,
                 kErrorHeightPx,
                 "stroke=\"" + m.colour + "\" stroke-opacity=\"0.8\" stroke-width=\"" +
                     Fixed(m.stroke_width, 1) + "\"");
    }
}

void Legend(std::ostream& out, const DemoPlotInput& input, double x, double y) {
    out << "<line x1=\"" << x << "\" y1=\"" << y << "\" x2=\"" << x + 30 << "\" y2=\"" << y
        << "\" stroke=\"black\" stroke-dasharray=\"5,3\"/><text x=\"" << x + 36 << "\" y=\""
        << y + 5 << "\">ground truth</text>\n";
    double lx = x + 160;
    for (size_t r = 0; r < input.ground_truth.size(); ++r, lx += 110) {
        out << "<line x1=\"" << lx << "\" y1=\"" << y << "\" x2=\"" << lx + 30 << "\" y2=\"" << y
            << "\" stroke=\"" << RobotColour(r) << "\" stroke-width=\"3\"/><text x=\"" << lx + 36
            << "\" y=\"" << y + 5 << "\">robot " << r << "</text>\n";
    }
    lx += 40;
    for (const auto& m : input.methods) {
        out << "<line x1=\"" << lx << "\" y1=\"" << y << "\" x2=\"" << lx + 30 << "\" y2=\"" << y
            << "\" stroke=\"" << m.colour << "\" stroke-width=\"3\"/><text x=\"" << lx + 36
            << "\" y=\"" << y + 5 << "\">" << m.name << " (error)</text>\n";
        lx += 60 + 8.0 * static_cast<double>(m.name.size()) + 60;
    }
}

}  // namespace

bool WriteDemoPlot(const std::string& path, const DemoPlotInput& input, std::string* error) {
    const Box box = MapExtent(input);
    const double map_h = kMapPanelWidthPx * (box.y1 - box.y0) / (box.x1 - box.x0);
    const int rows = (static_cast<int>(input.methods.size()) + kMapColumns - 1) / kMapColumns;
    const double width = kMapColumns * kMapPanelWidthPx + (kMapColumns + 1) * kGapPx;
    const double maps_bottom = 70.0 + rows * (map_h + kGapPx);
    const double height =
        maps_bottom + static_cast<double>(input.ground_truth.size()) * (kErrorHeightPx + kGapPx);
    std::ostringstream out;
    out << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << width << "\" height=\"" << height
        << "\" font-family=\"sans-serif\" font-size=\"13\">\n"
        << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n<text x=\"" << kGapPx
        << "\" y=\"22\" font-size=\"16\">" << input.title << "</text>\n";
    Legend(out, input, kGapPx, 44.0);
    for (size_t m = 0; m < input.methods.size(); ++m) {
        const std::size_t column = m % kMapColumns;
        const std::size_t row = m / kMapColumns;  // panel grid position (integer division)
        const double px = kGapPx + static_cast<double>(column) * (kMapPanelWidthPx + kGapPx);
        const double py = 70.0 + kGapPx / 2.0 + static_cast<double>(row) * (map_h + kGapPx);
        MapPanel(out, input, input.methods[m], box, px, py, kMapPanelWidthPx, map_h);
    }
    for (size_t r = 0; r < input.ground_truth.size(); ++r) {
        ErrorPanel(out, input, r, kGapPx,
                   maps_bottom + kGapPx / 2 + static_cast<double>(r) * (kErrorHeightPx + kGapPx),
                   width - 2 * kGapPx);
    }
    out << "</svg>\n";
    std::ofstream file(path);
    if (!file || !(file << out.str())) {
        *error = path + ": cannot write the plot";
        return false;
    }
    return true;
}

}  // namespace certislam::bin
