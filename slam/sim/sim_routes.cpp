// Default robot routes on the simulator's street grid.
#include "slam/sim/sim_routes.h"

#include <algorithm>
#include <random>

namespace certislam::slam {
namespace {

// Robots >= 2: a random walk on the grid's crossings that never turns back.
std::vector<Eigen::Vector2d> RandomWalk(const SimStreets& st, std::uint64_t seed, double length_m) {
    std::mt19937_64 rng(seed);
    const double p = st.block_pitch_m;
    auto node = [&](int i, int j) { return Eigen::Vector2d(i * p, j * p); };
    int i = std::uniform_int_distribution<int>(0, st.blocks_x)(rng);
    int j = std::uniform_int_distribution<int>(0, st.blocks_y)(rng);
    int di = 0;
    int dj = 0;
    std::vector<Eigen::Vector2d> route{node(i, j)};
    double length = 0.0;
    while (length < length_m) {
        std::vector<std::pair<int, int>> moves;
        for (auto [mi, mj] : {std::pair{1, 0}, {-1, 0}, {0, 1}, {0, -1}}) {
            const bool back = mi == -di && mj == -dj && (di != 0 || dj != 0);
            const int ni = i + mi;
            const int nj = j + mj;
            if (!back && ni >= 0 && ni <= st.blocks_x && nj >= 0 && nj <= st.blocks_y) {
                moves.emplace_back(mi, mj);
            }
        }
        const auto [mi, mj] =
            moves[std::uniform_int_distribution<size_t>(0, moves.size() - 1)(rng)];
        i += mi;
        j += mj;
        // Going straight on: extend the last leg instead of adding a collinear waypoint.
        if (mi == di && mj == dj && route.size() >= 2) route.pop_back();
        route.push_back(node(i, j));
        di = mi;
        dj = mj;
        length += p;
    }
    return route;
}

}  // namespace

std::vector<Eigen::Vector2d> DefaultRoute(const SimStreets& st, int robot, std::uint64_t seed,
                                          double length_m) {
    const double p = st.block_pitch_m;
    const double east = st.blocks_x * p;
    const double north = st.blocks_y * p;
    if (robot == 0) {
        // Loop around the grid back to the start (intra-robot loop closures), then drive the
        // first street again and up the first inner column.
        return {{0, 0}, {east, 0}, {east, north}, {0, north}, {0, 0}, {p, 0}, {p, north}};
    }
    if (robot == 1) {
        // Cross robot 0's streets, follow its southern street east, drive through the tunnel
        // and the east loop, come back along robot 0's northern street, then down robot 0's
        // column (opposite direction) and along the middle street.
        const double col = std::min(2, st.blocks_x) * p;
        std::vector<Eigen::Vector2d> r{
            {col, north}, {col, 0}, {st.east_loop_x, 0}, {st.east_loop_x, north}, {p, north}};
        if (st.blocks_y >= 2) {
            r.push_back({p, p});
            r.push_back({east, p});
        } else {
            r.push_back({p, 0});
        }
        return r;
    }
    return RandomWalk(st, seed, length_m);
}

}  // namespace certislam::slam
