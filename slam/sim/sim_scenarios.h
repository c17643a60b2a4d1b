// Named simulated missions (the demo's and `run`'s scenarios): world, routes, drift and start
// times fixed by a name and a seed, each chosen for what it shows about the back end.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "slam/sim/simulator.h"

namespace certislam::slam {

/// A named mission: the simulator settings and what it is for, in words.
struct SimScenario {
    std::string name;         ///< one of ScenarioNames()
    std::string description;  ///< the mission in a sentence (routes, drift, degeneracy)
    SimulatorConfig config;   ///< everything the simulator needs (seed, robots, routes, drift)
    /// Every k-th keyframe of a robot queries the loop matcher: with denser keyframes, the same
    /// queries per metre driven (each query costs a descriptor search and up to a GICP).
    int loop_query_stride = 1;
};

/// The scenarios, default first: "tunnel-rendezvous", "city", "large-drift", "swarm".
const std::vector<std::string>& ScenarioNames();

/// Robots a scenario has when none are asked for (2, or 8 for "swarm"); 0 for unknown names.
int ScenarioDefaultRobots(const std::string& name);

/// The seed a scenario is shown with when none is asked for: the mission its description and
/// the demo's Table I speak of (3 for "tunnel-rendezvous", 1 for the others).
std::uint64_t ScenarioDefaultSeed(const std::string& name);

/// The scenario `name` with `robots` robots (0: its default) and `seed`; robots beyond its
/// hand-made routes take seeded random walks. `sequential`: robot r starts when robot r-1 has
/// finished (as one vehicle's runs in the paper). std::nullopt for an unknown name.
std::optional<SimScenario> MakeScenario(const std::string& name, int robots, std::uint64_t seed,
                                        bool sequential = true);

}  // namespace certislam::slam
