// `certislam bench simulator`: time to generate the default simulated mission (all clouds).
#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <nlohmann/json.hpp>

#include "bin/command.h"
#include "slam/sim/simulator.h"

namespace certislam::bin {
namespace {

int RunSimulatorBench(int argc, char** argv) {
    CLI::App app{"Generates a simulated mission and reports how long it took"};
    bool json = false;
    int robots = 2;
    int rings = 32;
    std::uint64_t seed = 1;
    app.add_flag("--json", json, "machine-readable output");
    app.add_option("--robots", robots, "robots")->check(CLI::PositiveNumber);
    app.add_option("--rings", rings, "LiDAR rings (64: Ouster-like +-22.5 deg)")
        ->check(CLI::IsMember({32, 64}));
    app.add_option("--seed", seed, "mission seed");
    CLI11_PARSE(app, argc, argv);

    slam::SimulatorConfig cfg;
    cfg.num_robots = robots;
    cfg.seed = seed;
    if (rings == 64) cfg.lidar = slam::SimLidarConfig::Ouster64();
    const auto t0 = std::chrono::steady_clock::now();
    const slam::SimulatedMission mission = slam::SimulateMission(cfg);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    size_t keyframes = 0;
    size_t points = 0;
    for (const auto& robot : mission.robots) {
        for (const auto& kf : robot) {
            ++keyframes;
            points += kf.cloud->size();
        }
    }
    const double ms_per_kf = 1e3 * seconds / static_cast<double>(keyframes);
    const double pts_per_kf = static_cast<double>(points) / static_cast<double>(keyframes);
    if (json) {
        nlohmann::json j{{"robots", robots},
                         {"rings", rings},
                         {"keyframes", keyframes},
                         {"seconds", seconds},
                         {"ms_per_keyframe", ms_per_kf},
                         {"points_per_keyframe", pts_per_kf}};
        std::printf("%s\n", j.dump().c_str());
    } else {
        std::printf(
            "simulator: %d robots, %d rings: %zu keyframes in %.2f s (%.1f ms/keyframe, "
            "%.0f points/keyframe)\n",
            robots, rings, keyframes, seconds, ms_per_kf, pts_per_kf);
    }
    return 0;
}

const BenchRegistrar kBench{"simulator", "generate the default simulated mission (all clouds)",
                            RunSimulatorBench};

}  // namespace
}  // namespace certislam::bin
