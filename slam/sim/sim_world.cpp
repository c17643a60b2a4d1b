#include "slam/sim/sim_world.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>

#include "slam/core/check.h"

namespace certislam::slam {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

void Require(bool ok, const char* field, double value, const char* rule) {
    if (!ok) {
        throw std::invalid_argument(std::string("SimWorldConfig.") + field + " = " +
                                    std::to_string(value) + ": must be " + rule);
    }
}

// Slab test (Kay & Kajiya); returns the entry distance or +inf.
double IntersectBox(const SimBox& b, const Eigen::Vector3d& o, const Eigen::Vector3d& inv_d,
                    double t_min, double t_max) {
    double t_near = -kInf;
    double t_far = kInf;
    for (int k = 0; k < 3; ++k) {
        double t0 = (b.min[k] - o[k]) * inv_d[k];
        double t1 = (b.max[k] - o[k]) * inv_d[k];
        if (t0 > t1) std::swap(t0, t1);
        t_near = std::max(t_near, t0);
        t_far = std::min(t_far, t1);
    }
    if (t_near > t_far || t_near <= t_min || t_near > t_max) return kInf;
    return t_near;
}

double IntersectCylinder(const SimCylinder& c, const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                         double t_min, double t_max) {
    const double a = d.x() * d.x() + d.y() * d.y();
    if (a < 1e-12) return kInf;
    const double ox = o.x() - c.center.x();
    const double oy = o.y() - c.center.y();
    const double b = ox * d.x() + oy * d.y();
    const double cc = ox * ox + oy * oy - c.radius * c.radius;
    const double disc = b * b - a * cc;
    if (disc < 0.0) return kInf;
    const double t = (-b - std::sqrt(disc)) / a;
    if (t <= t_min || t > t_max) return kInf;
    const double z = o.z() + t * d.z();
    return (z >= c.z_min && z <= c.z_max) ? t : kInf;
}

double IntersectEllipsoid(const SimEllipsoid& e, const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                          double t_min, double t_max) {
    // Scaling z by radius_xy / radius_z turns the ellipsoid into a sphere and keeps t.
    const double s = e.radius_xy / e.radius_z;
    const Eigen::Vector3d oc(o.x() - e.center.x(), o.y() - e.center.y(),
                             (o.z() - e.center.z()) * s);
    const Eigen::Vector3d ds(d.x(), d.y(), d.z() * s);
    const double a = ds.squaredNorm();
    const double b = oc.dot(ds);
    const double cc = oc.squaredNorm() - e.radius_xy * e.radius_xy;
    const double disc = b * b - a * cc;
    if (disc < 0.0) return kInf;
    const double t = (-b - std::sqrt(disc)) / a;
    return (t > t_min && t <= t_max) ? t : kInf;
}

}  // namespace

void SimWorldConfig::Validate() const {
    Require(blocks_x >= 1, "blocks_x", blocks_x, ">= 1");
    Require(blocks_y >= 1, "blocks_y", blocks_y, ">= 1");
    Require(street_half_width_m > 0.0, "street_half_width_m", street_half_width_m, "> 0");
    Require(block_pitch_m > 2.0 * (street_half_width_m + 4.0), "block_pitch_m", block_pitch_m,
            "> 2 * (street_half_width_m + 4)");
    Require(building_min_height_m > 0.0, "building_min_height_m", building_min_height_m, "> 0");
    Require(building_max_height_m >= building_min_height_m, "building_max_height_m",
            building_max_height_m, ">= building_min_height_m");
    Require(tree_spacing_m > 0.0, "tree_spacing_m", tree_spacing_m, "> 0");
    Require(tunnel_length_m >= 0.0, "tunnel_length_m", tunnel_length_m, ">= 0");
    Require(tunnel_half_width_m > 0.0, "tunnel_half_width_m", tunnel_half_width_m, "> 0");
    Require(tunnel_height_m > 0.0, "tunnel_height_m", tunnel_height_m, "> 0");
    Require(tunnel_walkway_m >= 0.0 && tunnel_walkway_m < tunnel_half_width_m, "tunnel_walkway_m",
            tunnel_walkway_m, ">= 0 and < tunnel_half_width_m");
    Require(tunnel_approach_m > 0.0, "tunnel_approach_m", tunnel_approach_m, "> 0");
    Require(grid_cell_m > 0.0, "grid_cell_m", grid_cell_m, "> 0");
}

SimWorld::SimWorld(std::vector<SimBox> boxes, std::vector<SimCylinder> cylinders,
                   std::vector<SimEllipsoid> ellipsoids, bool ground, double grid_cell_m)
    : boxes_(std::move(boxes)),
      cylinders_(std::move(cylinders)),
      ellipsoids_(std::move(ellipsoids)),
      ground_(ground) {
    CERTISLAM_CHECK(grid_cell_m > 0.0);
    BuildGrid(grid_cell_m);
}

void SimWorld::BuildGrid(double cell_m) {
    cell_m_ = cell_m;
    Eigen::Vector2d lo = Eigen::Vector2d::Constant(kInf);
    Eigen::Vector2d hi = Eigen::Vector2d::Constant(-kInf);
    auto grow = [&](double x0, double y0, double x1, double y1) {
        lo = lo.cwiseMin(Eigen::Vector2d(x0, y0));
        hi = hi.cwiseMax(Eigen::Vector2d(x1, y1));
    };
    for (const auto& b : boxes_) grow(b.min.x(), b.min.y(), b.max.x(), b.max.y());
    for (const auto& c : cylinders_) {
        grow(c.center.x() - c.radius, c.center.y() - c.radius, c.center.x() + c.radius,
             c.center.y() + c.radius);
    }
    for (const auto& e : ellipsoids_) {
        grow(e.center.x() - e.radius_xy, e.center.y() - e.radius_xy, e.center.x() + e.radius_xy,
             e.center.y() + e.radius_xy);
    }
    if (!(lo.x() <= hi.x())) lo = hi = Eigen::Vector2d::Zero();
    grid_min_ = lo - Eigen::Vector2d::Constant(cell_m);
    nx_ = static_cast<int>(std::ceil((hi.x() - grid_min_.x()) / cell_m)) + 1;
    ny_ = static_cast<int>(std::ceil((hi.y() - grid_min_.y()) / cell_m)) + 1;
    // Two passes (count, fill) into a compressed row layout.
    std::vector<std::vector<Ref>> cells(static_cast<size_t>(nx_) * ny_);
    auto add = [&](Ref ref, double x0, double y0, double x1, double y1) {
        const int i0 = static_cast<int>(std::floor((x0 - grid_min_.x()) / cell_m));
        const int i1 = static_cast<int>(std::floor((x1 - grid_min_.x()) / cell_m));
        const int j0 = static_cast<int>(std::floor((y0 - grid_min_.y()) / cell_m));
        const int j1 = static_cast<int>(std::floor((y1 - grid_min_.y()) / cell_m));
        for (int j = std::max(j0, 0); j <= std::min(j1, ny_ - 1); ++j) {
            for (int i = std::max(i0, 0); i <= std::min(i1, nx_ - 1); ++i) {
                cells[static_cast<size_t>(j) * nx_ + i].push_back(ref);
            }
        }
    };
    for (std::uint32_t k = 0; k < boxes_.size(); ++k) {
        const auto& b = boxes_[k];
        add({Kind::kBox, k}, b.min.x(), b.min.y(), b.max.x(), b.max.y());
    }
    for (std::uint32_t k = 0; k < cylinders_.size(); ++k) {
        const auto& c = cylinders_[k];
        add({Kind::kCylinder, k}, c.center.x() - c.radius, c.center.y() - c.radius,
            c.center.x() + c.radius, c.center.y() + c.radius);
    }
    for (std::uint32_t k = 0; k < ellipsoids_.size(); ++k) {
        const auto& e = ellipsoids_[k];
        add({Kind::kEllipsoid, k}, e.center.x() - e.radius_xy, e.center.y() - e.radius_xy,
            e.center.x() + e.radius_xy, e.center.y() + e.radius_xy);
    }
    cell_begin_.assign(cells.size() + 1, 0);
    for (size_t c = 0; c < cells.size(); ++c) {
        cell_begin_[c + 1] = cell_begin_[c] + static_cast<std::uint32_t>(cells[c].size());
    }
    cell_refs_.clear();
    cell_refs_.reserve(cell_begin_.back());
    for (const auto& cell : cells) cell_refs_.insert(cell_refs_.end(), cell.begin(), cell.end());
}

double SimWorld::Intersect(const Ref& ref, const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                           const Eigen::Vector3d& inv_d, double t_min, double t_max) const {
    switch (ref.kind) {
        case Kind::kBox:
            return IntersectBox(boxes_[ref.index], o, inv_d, t_min, t_max);
        case Kind::kCylinder:
            return IntersectCylinder(cylinders_[ref.index], o, d, t_min, t_max);
        case Kind::kEllipsoid:
            return IntersectEllipsoid(ellipsoids_[ref.index], o, d, t_min, t_max);
    }
    return kInf;
}

std::optional<SimHit> SimWorld::CastRay(const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                                        double t_min, double t_max) const {
    double best = t_max;
    bool hit = false;
    if (ground_ && d.z() < 0.0) {
        const double t_ground = -o.z() / d.z();
        if (t_ground > t_min && t_ground <= best) {
            best = t_ground;
            hit = true;
        }
    }
    const Eigen::Vector3d inv_d = d.cwiseInverse();
    // Clip the ray to the grid rectangle.
    double t0 = t_min;
    double t1 = best;
    const double gx1 = grid_min_.x() + nx_ * cell_m_;
    const double gy1 = grid_min_.y() + ny_ * cell_m_;
    for (int k = 0; k < 2; ++k) {
        const double lo = k == 0 ? grid_min_.x() : grid_min_.y();
        const double hi = k == 0 ? gx1 : gy1;
        if (d[k] == 0.0) {
            if (o[k] < lo || o[k] >= hi) t1 = -kInf;  // parallel to and outside the grid
            continue;
        }
        double a = (lo - o[k]) * inv_d[k];
        double b = (hi - o[k]) * inv_d[k];
        if (a > b) std::swap(a, b);
        t0 = std::max(t0, a);
        t1 = std::min(t1, b);
    }
    if (t0 < t1) {
        const double px = o.x() + t0 * d.x();
        const double py = o.y() + t0 * d.y();
        int ix =
            std::clamp(static_cast<int>(std::floor((px - grid_min_.x()) / cell_m_)), 0, nx_ - 1);
        int iy =
            std::clamp(static_cast<int>(std::floor((py - grid_min_.y()) / cell_m_)), 0, ny_ - 1);
        const int step_x = d.x() > 0.0 ? 1 : -1;
        const int step_y = d.y() > 0.0 ? 1 : -1;
        const double delta_x = d.x() != 0.0 ? cell_m_ * std::abs(inv_d.x()) : kInf;
        const double delta_y = d.y() != 0.0 ? cell_m_ * std::abs(inv_d.y()) : kInf;
        double next_x = d.x() != 0.0
                            ? (grid_min_.x() + (ix + (step_x > 0)) * cell_m_ - o.x()) * inv_d.x()
                            : kInf;
        double next_y = d.y() != 0.0
                            ? (grid_min_.y() + (iy + (step_y > 0)) * cell_m_ - o.y()) * inv_d.y()
                            : kInf;
        while (true) {
            const size_t c = static_cast<size_t>(iy) * nx_ + ix;
            for (std::uint32_t r = cell_begin_[c]; r < cell_begin_[c + 1]; ++r) {
                const double t = Intersect(cell_refs_[r], o, d, inv_d, t_min, best);
                if (t < best) {
                    best = t;
                    hit = true;
                }
            }
            const double t_exit = std::min(next_x, next_y);
            if (best <= t_exit || t_exit >= t1) break;
            if (next_x < next_y) {
                ix += step_x;
                next_x += delta_x;
                if (ix < 0 || ix >= nx_) break;
            } else {
                iy += step_y;
                next_y += delta_y;
                if (iy < 0 || iy >= ny_) break;
            }
        }
    }
    if (!hit) return std::nullopt;
    return SimHit{best};
}

}  // namespace certislam::slam
