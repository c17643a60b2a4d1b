// An analytic outdoor world (ground, box buildings, trees, a tunnel) and fast ray casting in it.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <vector>

namespace certislam::slam {

/// An axis-aligned box (buildings, tunnel walls and roof), world frame, metres.
struct SimBox {
    Eigen::Vector3d min = Eigen::Vector3d::Zero();  ///< lower corner
    Eigen::Vector3d max = Eigen::Vector3d::Zero();  ///< upper corner
};

/// A vertical cylinder (tree trunk) from z_min to z_max.
struct SimCylinder {
    Eigen::Vector2d center = Eigen::Vector2d::Zero();  ///< axis position in x-y
    double radius = 0.2;                               ///< metres
    double z_min = 0.0;                                ///< bottom height
    double z_max = 3.0;                                ///< top height
};

/// An ellipsoid with vertical axis (tree crown): radius `radius_xy` in x-y, `radius_z` in z.
struct SimEllipsoid {
    Eigen::Vector3d center = Eigen::Vector3d::Zero();  ///< centre
    double radius_xy = 2.0;                            ///< horizontal semi-axis, metres
    double radius_z = 2.0;                             ///< vertical semi-axis, metres
};

/// A node of the street grid or of the tunnel loop, where routes turn.
using SimNode = Eigen::Vector2d;

/// The street layout the world was built from, so routes can be planned on it.
struct SimStreets {
    double block_pitch_m = 40.0;  ///< distance between parallel streets
    int blocks_x = 3;             ///< blocks along x (streets at x = 0, pitch, ..., blocks_x*pitch)
    int blocks_y = 2;             ///< blocks along y
    double tunnel_x_begin = 0.0;  ///< tunnel entrance (x), on the street y = 0 east of the grid
    double tunnel_x_end = 0.0;    ///< tunnel exit (x)
    double east_loop_x = 0.0;     ///< x of the north-south street closing the tunnel loop
    double tunnel_half_width = 0;  ///< half the inner width of the tunnel
};

/// Parameters of the procedurally generated world.
struct SimWorldConfig {
    int blocks_x = 3;                     ///< city blocks along x, >= 1
    int blocks_y = 2;                     ///< city blocks along y, >= 1
    double block_pitch_m = 40.0;          ///< street spacing, > 2*(street_half_width_m + 4)
    double street_half_width_m = 6.0;     ///< half width of a street incl. sidewalk, > 0
    double building_min_height_m = 6.0;   ///< lower bound of building heights, > 0
    double building_max_height_m = 25.0;  ///< upper bound, >= building_min_height_m
    double tree_spacing_m = 9.0;          ///< mean spacing of street trees along a sidewalk, > 0
    double tunnel_length_m = 100.0;       ///< length of the featureless tunnel, >= 0 (0: none)
    double tunnel_half_width_m = 5.0;     ///< inner half width of the tunnel, > 0
    double tunnel_height_m = 6.0;         ///< inner height of the tunnel roof, > 0
    /// Width of a raised walkway (1 m high) along the tunnel's north wall, [0, tunnel half width):
    /// breaks the tunnel's 180-degree symmetry, not its along-axis degeneracy (0: none).
    double tunnel_walkway_m = 0.0;
    double tunnel_approach_m = 25.0;  ///< open street before and after the tunnel, > 0
    double grid_cell_m = 8.0;         ///< cell size of the ray-casting acceleration grid, > 0

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// A ray-surface hit: distance along the (unit) direction.
struct SimHit {
    double t = 0.0;  ///< metres along the ray
};

/// The analytic world: ground plane z = 0 plus primitives, bucketed in a uniform x-y grid so a
/// ray visits only the cells it crosses (Amanatides & Woo 1987 traversal).
class SimWorld {
  public:
    /// Builds a world from explicit primitives (tests); `grid_cell_m` sizes the acceleration grid.
    SimWorld(std::vector<SimBox> boxes, std::vector<SimCylinder> cylinders,
             std::vector<SimEllipsoid> ellipsoids, bool ground, double grid_cell_m = 8.0);

    /// Nearest hit of the ray origin + t * direction (direction unit length) with t in
    /// (t_min, t_max], or nothing.
    std::optional<SimHit> CastRay(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                                  double t_min, double t_max) const;

    const std::vector<SimBox>& boxes() const { return boxes_; }                  ///< all boxes
    const std::vector<SimCylinder>& cylinders() const { return cylinders_; }     ///< all trunks
    const std::vector<SimEllipsoid>& ellipsoids() const { return ellipsoids_; }  ///< crowns

  private:
    enum class Kind : std::uint8_t { kBox, kCylinder, kEllipsoid };
    struct Ref {
        Kind kind;
        std::uint32_t index;
    };
    void BuildGrid(double cell_m);
    double Intersect(const Ref& ref, const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                     const Eigen::Vector3d& inv_d, double t_min, double t_max) const;

    std::vector<SimBox> boxes_;
    std::vector<SimCylinder> cylinders_;
    std::vector<SimEllipsoid> ellipsoids_;
    bool ground_ = true;
    double cell_m_ = 8.0;
    Eigen::Vector2d grid_min_ = Eigen::Vector2d::Zero();
    int nx_ = 0;
    int ny_ = 0;
    std::vector<std::uint32_t> cell_begin_;  // CSR: refs of cell c are [begin[c], begin[c+1])
    std::vector<Ref> cell_refs_;
};

}  // namespace certislam::slam
