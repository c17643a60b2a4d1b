// Writes the seed corpus of fuzz_submap: real submaps (a few scans of a box room integrated into a
// TSDF at two voxel sizes), serialized as a mapper sends them. Usage: fuzz_submap_seeds DIR
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "slam/mapping/submap.h"

namespace {

using namespace certislam::slam;

// A 3 m x 2 m x 1.6 m room seen from its centre: one point per ray on the nearest wall.
PointCloud Room() {
    PointCloud cloud;
    cloud.reserve(40 * 5);
    for (int a = 0; a < 40; ++a) {
        for (int e = -2; e <= 2; ++e) {
            const double az = 2.0 * M_PI * a / 40.0;
            const double el = 0.2 * e;
            const Eigen::Vector3d dir(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az),
                                      std::sin(el));
            const double s = std::min({1.5 / std::max(std::abs(dir.x()), 1e-9),
                                       1.0 / std::max(std::abs(dir.y()), 1e-9),
                                       0.8 / std::max(std::abs(dir.z()), 1e-9)});
            cloud.push_back((s * dir).cast<float>());
        }
    }
    return cloud;
}

}  // namespace

int main(int argc, char** argv) {
    if (argc != 2) {
        std::fprintf(stderr, "usage: fuzz_submap_seeds DIR\n");
        return 1;
    }
    std::filesystem::create_directories(argv[1]);
    int written = 0;
    for (const double voxel : {0.4, 0.8}) {
        TsdfConfig config;
        config.voxel_size_m = voxel;
        Submap submap{SubmapId{1, written},
                      PoseId{1, 3 * written},
                      Eigen::Isometry3d::Identity(),
                      {0, 1},
                      TsdfVolume(config)};
        submap.T_world_submap.translation() = Eigen::Vector3d(1.0, -2.0, 0.5);
        Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
        submap.volume.Integrate(Room(), pose);
        pose.translation().x() = 0.3;
        submap.volume.Integrate(Room(), pose);
        for (const int bits : {32, 8}) {  // lossless, and quantised as a mapper sends it
            std::ofstream(std::string(argv[1]) + "/submap" + std::to_string(written++) + ".bin",
                          std::ios::binary)
                << SerializeSubmap(submap, bits);
        }
    }
    std::printf("%d submap seeds in %s\n", written, argv[1]);
    return 0;
}
