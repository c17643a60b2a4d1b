// Named simulated missions.
#include "slam/sim/sim_scenarios.h"

#include <algorithm>

namespace certislam::slam {
namespace {

using Route = std::vector<Eigen::Vector2d>;

/// The street layout GenerateWorld gives for `world` (pure arithmetic on the config).
SimStreets Layout(const SimWorldConfig& world) {
    SimStreets st;
    st.block_pitch_m = world.block_pitch_m;
    st.blocks_x = world.blocks_x;
    st.blocks_y = world.blocks_y;
    st.tunnel_x_begin = world.blocks_x * world.block_pitch_m + world.tunnel_approach_m;
    st.tunnel_x_end = st.tunnel_x_begin + world.tunnel_length_m;
    st.east_loop_x = st.tunnel_x_end + world.tunnel_approach_m;
    return st;
}

/// Today's city: the default world, routes and drift; odometry slips 5 % in the short tunnel.
void City(SimScenario* s) {
    s->config.tunnel_slip = 0.05;
    s->description =
        "robots on overlapping routes through a city grid with a short tunnel loop; mild "
        "LiDAR-inertial drift; odometry slips 5 % in the tunnel";
}

/// Robot 0 drives from the city through a 120 m featureless tunnel, robot 1 starts inside it (a
/// SubT-style deployment) and follows the same way out: their first common places are the tunnel,
/// where registration is degenerate along the axis; later they meet on structured streets.
/// LiDAR-inertial drift is strong (yaw-rate and vertical-velocity bias random walks) and the
/// odometry misses 8 % of the motion along the tunnel (scale error).
void TunnelRendezvous(SimScenario* s) {
    SimulatorConfig& c = s->config;
    c.world.blocks_x = 2;
    c.world.tunnel_length_m = 120.0;
    c.world.tunnel_walkway_m = 1.2;  // a real tunnel is not symmetric under a half turn
    // Several hundred keyframes per robot, as a LiDAR-inertial front end gives; every other one
    // queries the loop matcher (a query every 4 m, as the other scenarios').
    c.keyframe_spacing_m = 2.0;
    s->loop_query_stride = 2;
    c.tunnel_slip = 0.08;
    c.drift.yaw_rate_bias_sigma_rad_s = 1.5e-3;
    c.drift.yaw_rate_bias_walk_rad_s_sqrt_s = 1.5e-4;
    c.drift.vertical_velocity_bias_sigma_m_s = 8e-3;
    c.drift.vertical_velocity_bias_walk_m_s_sqrt_s = 8e-4;
    c.drift.scale_error_sigma = 1e-2;
    const SimStreets st = Layout(c.world);
    const double p = st.block_pitch_m;
    const double north = st.blocks_y * p;
    // Robot 0 sets off westward, robot 1 eastward: their odometry frames differ by a half turn.
    c.routes = {
        {{p, p}, {0, p}, {0, 0}, {st.east_loop_x, 0}, {st.east_loop_x, north}, {p, north}, {p, p}},
        {{st.tunnel_x_begin + 20.0, 0},
         {st.east_loop_x, 0},
         {st.east_loop_x, north},
         {0, north},
         {0, 0},
         {p, 0}},
    };
    s->description =
        "robot 0 sets off west and drives from the city through a 120 m featureless tunnel; "
        "robot 1 starts inside the tunnel and drives out east (their odometry frames half a "
        "turn apart), so the robots first share places in the tunnel "
        "(registration degenerate along its axis), later on structured streets; strong "
        "LiDAR-inertial drift (yaw-rate and vertical-velocity bias random walks), odometry "
        "misses 8 % of the motion in the tunnel";
}

/// Two long loops around a larger grid with heavy yaw-rate bias: tens of degrees of rotational
/// drift, where local search from odometry or a one-time alignment can stop in a local minimum.
void LargeDrift(SimScenario* s) {
    SimulatorConfig& c = s->config;
    c.world.blocks_x = 4;
    c.world.blocks_y = 3;
    c.world.tunnel_length_m = 60.0;
    c.tunnel_slip = 0.05;
    c.drift.yaw_rate_bias_sigma_rad_s = 3e-3;
    c.drift.yaw_rate_bias_walk_rad_s_sqrt_s = 3e-4;
    c.drift.scale_error_sigma = 1e-2;
    const SimStreets st = Layout(c.world);
    const double p = st.block_pitch_m;
    const double east = st.blocks_x * p;
    const double north = st.blocks_y * p;
    c.routes = {
        // Each robot ends on a street it began on, driving the same way: its own loop closes.
        {{0, 0}, {east, 0}, {east, north}, {0, north}, {0, 0}, {2 * p, 0}},
        // Robot 1 sets off westward, facing away from robot 0's start: its odometry frame is
        // half a turn from robot 0's, so every pose of the odometry-only guess is far off.
        {{east, 2 * p},
         {0, 2 * p},
         {0, 0},
         {2 * p, 0},
         {2 * p, north},
         {east, north},
         {east, 2 * p},
         {2 * p, 2 * p}},
    };
    s->description =
        "two robots on long loops around a 4 x 3 block grid, crossing each other's streets in "
        "both directions, setting off half a turn apart; heavy yaw-rate bias (about 25 degrees "
        "of rotational drift)";
}

/// Eight robots on seeded random walks over the grid, each starting when the previous ends:
/// pairs meet at different times and places.
void Swarm(SimScenario* s) {
    SimulatorConfig& c = s->config;
    c.tunnel_slip = 0.05;
    c.keyframe_spacing_m = 4.0;
    c.random_route_length_m = 280.0;
    const SimStreets st = Layout(c.world);
    const double p = st.block_pitch_m;
    const double east = st.blocks_x * p;
    const double north = st.blocks_y * p;
    // Robots 0 and 1 cover the grid's ring and its middle so every random walk meets one.
    c.routes = {
        {{0, 0}, {east, 0}, {east, north}, {0, north}, {0, p}, {east, p}},
        {{p, north}, {p, 0}, {2 * p, 0}, {2 * p, north}},
    };
    s->description =
        "eight robots on overlapping routes (two around and across the grid, six seeded random "
        "walks), one after another, meeting pairwise at different times";
}

/// Robot r starts when robot r-1 has finished (the longest route's duration plus 10 s).
void Sequential(SimulatorConfig* config) {
    const MissionGenerator plan(*config);
    double longest_s = 0.0;
    for (int r = 0; r < plan.num_robots(); ++r) {
        const int last = plan.num_keyframes(r) - 1;
        const auto ns = plan.PoseOnly(r, last).stamp_ns - plan.PoseOnly(r, 0).stamp_ns;
        longest_s = std::max(longest_s, static_cast<double>(ns) * 1e-9);
    }
    config->robot_start_interval_s = longest_s + 10.0;
}

}  // namespace

const std::vector<std::string>& ScenarioNames() {
    static const std::vector<std::string> names{"tunnel-rendezvous", "city", "large-drift",
                                                "swarm"};
    return names;
}

std::uint64_t ScenarioDefaultSeed(const std::string& name) {
    // Seed 3 draws drift under which LM from odometry stops at a critical point (the
    // certificate's refusal is the demo's point); with seed 1 it stops short of one.
    return name == "tunnel-rendezvous" ? 3 : 1;
}

int ScenarioDefaultRobots(const std::string& name) {
    if (name == "swarm") return 8;
    const auto& names = ScenarioNames();
    return std::find(names.begin(), names.end(), name) != names.end() ? 2 : 0;
}

std::optional<SimScenario> MakeScenario(const std::string& name, int robots, std::uint64_t seed,
                                        bool sequential) {
    if (ScenarioDefaultRobots(name) == 0) return std::nullopt;
    SimScenario s;
    s.name = name;
    s.config.seed = seed;
    s.config.num_robots = robots > 0 ? robots : ScenarioDefaultRobots(name);
    if (name == "city") City(&s);
    if (name == "tunnel-rendezvous") TunnelRendezvous(&s);
    if (name == "large-drift") LargeDrift(&s);
    if (name == "swarm") Swarm(&s);
    if (sequential) Sequential(&s.config);
    return s;
}

}  // namespace certislam::slam
