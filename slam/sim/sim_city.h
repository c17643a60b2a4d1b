// Procedural generation of the simulator's city: streets, buildings, trees and the tunnel loop.
#pragma once

#include <cstdint>

#include "slam/sim/sim_world.h"

namespace certislam::slam {

/// A generated world together with the street layout routes are planned on.
struct GeneratedWorld {
    SimWorld world;      ///< the geometry
    SimStreets streets;  ///< where the streets and the tunnel are
};

/// Generates the city: a grid of streets with box buildings in the blocks, trees along the
/// sidewalks, and east of the grid a loop whose southern street runs through a tunnel (two
/// parallel walls and a roof, featureless along its axis). The same seed gives the same world.
GeneratedWorld GenerateWorld(const SimWorldConfig& config, std::uint64_t seed);

}  // namespace certislam::slam
