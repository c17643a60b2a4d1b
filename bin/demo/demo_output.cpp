// SVG plot (hand-written polylines), stderr progress bar.
#include "bin/demo/demo_output.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>

namespace certislam::bin {
namespace {

constexpr double kCanvasPx = 900.0;  ///< plot area size
constexpr double kMarginPx = 40.0;   ///< margin around the plot area
constexpr double kLegendPx = 260.0;  ///< legend column on the right

}  // namespace

bool WriteTrajectorySvg(const std::string& path, const std::string& title,
                        const std::vector<PlotSeries>& series, std::string* error) {
    double xmin = 1e300, xmax = -1e300, ymin = 1e300, ymax = -1e300;
    for (const auto& s : series) {
        for (const auto& traj : s.robots) {
            for (const auto& p : traj) {
                const Eigen::Vector3d t = p.T_world_body.translation();
                xmin = std::min(xmin, t.x());
                xmax = std::max(xmax, t.x());
                ymin = std::min(ymin, t.y());
                ymax = std::max(ymax, t.y());
            }
        }
    }
    if (xmin > xmax) xmin = ymin = 0, xmax = ymax = 1;
    const double span = std::max({xmax - xmin, ymax - ymin, 1.0});
    const double scale = kCanvasPx / span;
    const auto px = [&](double x) { return kMarginPx + (x - xmin) * scale; };
    const auto py = [&](double y) { return kMarginPx + (ymax - y) * scale; };  // y up
    std::ofstream out(path);
    if (!out) {
        *error = path + ": cannot open for writing";
        return false;
    }
    const double width = kCanvasPx + 2 * kMarginPx + kLegendPx;
    const double height = (ymax - ymin) * scale + 2 * kMarginPx + 30;
    out << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << width << "\" height=\"" << height
        << "\" font-family=\"sans-serif\" font-size=\"14\">\n"
        << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
        << "<text x=\"" << kMarginPx << "\" y=\"24\" font-size=\"16\">" << title << "</text>\n";
    out.precision(6);
    for (size_t k = 0; k < series.size(); ++k) {
        const auto& s = series[k];
        for (const auto& traj : s.robots) {
            out << "<polyline fill=\"none\" stroke=\"" << s.colour << "\" stroke-width=\"1.5\""
                << (s.dashed ? " stroke-dasharray=\"6,4\"" : "") << " points=\"";
            for (const auto& p : traj) {
                out << px(p.T_world_body.translation().x()) << ","
                    << py(p.T_world_body.translation().y()) << " ";
            }
            out << "\"/>\n";
        }
        const double ly = kMarginPx + 24.0 * static_cast<double>(k);
        const double lx = kCanvasPx + 2 * kMarginPx;
        out << "<line x1=\"" << lx << "\" y1=\"" << ly << "\" x2=\"" << lx + 30 << "\" y2=\"" << ly
            << "\" stroke=\"" << s.colour << "\" stroke-width=\"3\""
            << (s.dashed ? " stroke-dasharray=\"6,4\"" : "") << "/>\n<text x=\"" << lx + 38
            << "\" y=\"" << ly + 5 << "\">" << s.label << "</text>\n";
    }
    const double bar_m = std::pow(10.0, std::floor(std::log10(span / 4)));
    const double by = height - 15;
    out << "<line x1=\"" << kMarginPx << "\" y1=\"" << by << "\" x2=\"" << kMarginPx + bar_m * scale
        << "\" y2=\"" << by << "\" stroke=\"black\" stroke-width=\"3\"/>\n<text x=\""
        << kMarginPx + bar_m * scale + 8 << "\" y=\"" << by + 5 << "\">" << bar_m
        << " m</text>\n</svg>\n";
    if (!out) *error = path + ": write failed";
    return static_cast<bool>(out);
}

void ProgressBar::Update(const std::string& stage, double fraction) {
    if (!enabled_) return;
    const int percent = static_cast<int>(std::lround(100.0 * std::clamp(fraction, 0.0, 1.0)));
    if (percent == last_percent_ && stage == last_stage_) return;
    last_percent_ = percent;
    last_stage_ = stage;
    constexpr int kWidth = 30;
    const int filled = percent * kWidth / 100;
    std::fprintf(stderr, "\r[%s%s] %3d%% %-40s", std::string(filled, '#').c_str(),
                 std::string(kWidth - filled, '.').c_str(), percent, stage.c_str());
    std::fflush(stderr);
}

void ProgressBar::Done() {
    if (enabled_) std::fprintf(stderr, "\n");
}

}  // namespace certislam::bin
