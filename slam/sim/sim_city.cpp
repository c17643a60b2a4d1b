// Procedural generation of the simulator's city.
#include "slam/sim/sim_city.h"

#include <cmath>
#include <random>

namespace certislam::slam {
namespace {

struct Builder {
    const SimWorldConfig& cfg;
    std::mt19937_64 rng;
    std::vector<SimBox> boxes;
    std::vector<SimCylinder> trunks;
    std::vector<SimEllipsoid> crowns;

    double Uniform(double lo, double hi) { return std::uniform_real_distribution<>(lo, hi)(rng); }

    void Building(double x0, double y0, double x1, double y1) {
        const double h = Uniform(cfg.building_min_height_m, cfg.building_max_height_m);
        boxes.push_back({Eigen::Vector3d(x0, y0, 0.0), Eigen::Vector3d(x1, y1, h)});
    }

    // A row of buildings along one side of the block [x0,x1]x[y0,y1]: `side` 0..3 = S, N, W, E.
    void BuildingRow(double x0, double y0, double x1, double y1, int side) {
        const bool along_x = side < 2;
        const double from = along_x ? x0 : y0;
        const double to = along_x ? x1 : y1;
        const double max_depth = 0.45 * (along_x ? (y1 - y0) : (x1 - x0));
        double s = from + Uniform(0.0, 3.0);
        while (s < to - 4.0) {
            const double len = std::min(Uniform(7.0, 16.0), to - s);
            const double depth = Uniform(0.5, 1.0) * max_depth;
            const double setback = Uniform(0.0, 2.5);
            if (Uniform(0.0, 1.0) > 0.15) {  // some lots stay empty (gaps, parking)
                switch (side) {
                    case 0:
                        Building(s, y0 + setback, s + len, y0 + setback + depth);
                        break;
                    case 1:
                        Building(s, y1 - setback - depth, s + len, y1 - setback);
                        break;
                    case 2:
                        Building(x0 + setback, s, x0 + setback + depth, s + len);
                        break;
                    default:
                        Building(x1 - setback - depth, s, x1 - setback, s + len);
                        break;
                }
            }
            s += len + Uniform(1.0, 5.0);
        }
    }

    void Block(double x0, double y0, double x1, double y1) {
        for (int side = 0; side < 4; ++side) BuildingRow(x0, y0, x1, y1, side);
    }

    void Tree(double x, double y) {
        const double trunk_h = Uniform(2.6, 4.0);
        const double r = Uniform(1.5, 3.0);
        const double rz = r * Uniform(0.9, 1.4);
        trunks.push_back({Eigen::Vector2d(x, y), Uniform(0.15, 0.35), 0.0, trunk_h + 0.3 * rz});
        crowns.push_back({Eigen::Vector3d(x, y, trunk_h + 0.7 * rz), r, rz});
    }

    // Trees on both sidewalks of the straight street a -> b, none near its ends (crossings).
    void StreetTrees(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
        const double len = (b - a).norm();
        const Eigen::Vector2d u = (b - a) / len;
        const Eigen::Vector2d n(-u.y(), u.x());
        const double offset = cfg.street_half_width_m - 0.8;
        const double keep_clear = cfg.street_half_width_m + 2.0;
        for (double side : {-1.0, 1.0}) {
            double s = keep_clear + Uniform(0.0, cfg.tree_spacing_m);
            while (s < len - keep_clear) {
                const Eigen::Vector2d p = a + s * u + side * offset * n;
                if (Uniform(0.0, 1.0) > 0.2) Tree(p.x(), p.y());
                s += cfg.tree_spacing_m * Uniform(0.6, 1.4);
            }
        }
    }

    void Tunnel(double x0, double x1) {
        const double w = cfg.tunnel_half_width_m;
        const double h = cfg.tunnel_height_m;
        const double t = kWallThickness;
        boxes.push_back({Eigen::Vector3d(x0, w, 0.0), Eigen::Vector3d(x1, w + t, h + t)});
        boxes.push_back({Eigen::Vector3d(x0, -w - t, 0.0), Eigen::Vector3d(x1, -w, h + t)});
        boxes.push_back({Eigen::Vector3d(x0, -w - t, h), Eigen::Vector3d(x1, w + t, h + t)});
        if (cfg.tunnel_walkway_m > 0.0) {
            boxes.push_back({Eigen::Vector3d(x0, w - cfg.tunnel_walkway_m, 0.0),
                             Eigen::Vector3d(x1, w, kWalkwayHeight)});
        }
    }

    static constexpr double kWallThickness = 0.6;
    static constexpr double kWalkwayHeight = 1.0;
};

}  // namespace

GeneratedWorld GenerateWorld(const SimWorldConfig& cfg, std::uint64_t seed) {
    cfg.Validate();
    Builder b{cfg, std::mt19937_64(seed), {}, {}, {}};
    const double p = cfg.block_pitch_m;
    const double hw = cfg.street_half_width_m;
    const double east = cfg.blocks_x * p;
    const double north = cfg.blocks_y * p;
    // The grid's blocks plus a ring of blocks west, south and north of it (east is the loop).
    for (int j = -1; j <= cfg.blocks_y; ++j) {
        for (int i = -1; i < cfg.blocks_x; ++i) {
            b.Block(i * p + hw, j * p + hw, (i + 1) * p - hw, (j + 1) * p - hw);
        }
    }
    for (int j = 0; j <= cfg.blocks_y; ++j) {
        for (int i = 0; i < cfg.blocks_x; ++i) {
            b.StreetTrees({i * p, j * p}, {(i + 1) * p, j * p});
        }
    }
    for (int i = 0; i <= cfg.blocks_x; ++i) {
        for (int j = 0; j < cfg.blocks_y; ++j) {
            b.StreetTrees({i * p, j * p}, {i * p, (j + 1) * p});
        }
    }
    // East loop: y = 0 through the tunnel, x = loop_x north, y = north back west.
    SimStreets streets;
    streets.block_pitch_m = p;
    streets.blocks_x = cfg.blocks_x;
    streets.blocks_y = cfg.blocks_y;
    streets.tunnel_half_width = cfg.tunnel_half_width_m;
    streets.tunnel_x_begin = east + cfg.tunnel_approach_m;
    streets.tunnel_x_end = streets.tunnel_x_begin + cfg.tunnel_length_m;
    streets.east_loop_x = streets.tunnel_x_end + cfg.tunnel_approach_m;
    if (cfg.tunnel_length_m > 0.0) b.Tunnel(streets.tunnel_x_begin, streets.tunnel_x_end);
    b.StreetTrees({east, 0.0}, {streets.tunnel_x_begin + hw, 0.0});
    b.StreetTrees({streets.tunnel_x_end - hw, 0.0}, {streets.east_loop_x, 0.0});
    b.StreetTrees({streets.east_loop_x, 0.0}, {streets.east_loop_x, north});
    b.StreetTrees({east, north}, {streets.east_loop_x, north});
    // A few scattered halls inside the loop, clear of the streets.
    for (double x = east + hw + 4.0; x + 14.0 < streets.east_loop_x - hw - 4.0;
         x += b.Uniform(25.0, 40.0)) {
        const double y_lo = hw + cfg.tunnel_half_width_m + 4.0;
        const double y_hi = north - hw - 18.0;
        if (y_hi <= y_lo) break;
        const double y = b.Uniform(y_lo, y_hi);
        b.Building(x, y, x + b.Uniform(8.0, 14.0), y + b.Uniform(8.0, 14.0));
    }
    SimWorld world(std::move(b.boxes), std::move(b.trunks), std::move(b.crowns), true,
                   cfg.grid_cell_m);
    return {std::move(world), streets};
}

}  // namespace certislam::slam
