// Default robot routes on the simulator's street grid.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "slam/sim/sim_world.h"

namespace certislam::slam {

/// The default route (street-centreline waypoints) of `robot` in a world laid out as `streets`:
/// robot 0 loops the grid and revisits its start, robot 1 crosses robot 0's streets, drives the
/// tunnel loop and comes back; further robots take seeded random walks on the grid.
std::vector<Eigen::Vector2d> DefaultRoute(const SimStreets& streets, int robot, std::uint64_t seed,
                                          double length_m);

}  // namespace certislam::slam
