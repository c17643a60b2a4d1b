// Voxel-grid downsampling: hash of integer voxel coordinates -> running centroid.
#include "slam/frontend/downsample.h"

#include <cmath>
#include <cstdint>
#include <vector>

#include "slam/core/check.h"

namespace certislam::slam {

PointCloud VoxelDownsample(const PointCloud& cloud, double voxel_m) {
    CERTISLAM_CHECK(voxel_m > 0.0);
    const double inv = 1.0 / voxel_m;
    // 21 bits per axis: +-1M voxels, i.e. +-200 km at 0.2 m; farther points share voxels.
    auto key = [inv](const Eigen::Vector3f& p) {
        std::uint64_t k = 0;
        for (int a = 0; a < 3; ++a) {
            const auto v = static_cast<std::int64_t>(std::floor(p[a] * inv));
            k = (k << 21) | (static_cast<std::uint64_t>(v) & 0x1fffff);
        }
        return k;
    };
    // Open addressing with linear probing in a power-of-two table of at least twice the points
    // (load <= 1/2): std::unordered_map allocated a node per voxel, and Debian 12's Boost
    // predates unordered_flat_map.
    int bits = 4;
    while ((std::size_t{1} << bits) < 2 * cloud.size()) ++bits;
    const std::size_t mask = (std::size_t{1} << bits) - 1;
    constexpr std::uint32_t kEmpty = 0xffffffffu;
    std::vector<std::uint64_t> keys(mask + 1);
    std::vector<std::uint32_t> slots(mask + 1, kEmpty);
    std::vector<Eigen::Vector3d> sums;
    std::vector<std::uint32_t> counts;
    for (const Eigen::Vector3f& p : cloud) {
        if (!p.allFinite()) continue;
        const std::uint64_t k = key(p);
        std::size_t h = (k * 0x9e3779b97f4a7c15ull) >> (64 - bits);  // Fibonacci hashing
        while (slots[h] != kEmpty && keys[h] != k) h = (h + 1) & mask;
        if (slots[h] == kEmpty) {
            keys[h] = k;
            slots[h] = static_cast<std::uint32_t>(sums.size());
            sums.emplace_back(Eigen::Vector3d::Zero());
            counts.push_back(0);
        }
        sums[slots[h]] += p.cast<double>();
        ++counts[slots[h]];
    }
    PointCloud out(sums.size());
    for (std::size_t i = 0; i < sums.size(); ++i) out[i] = (sums[i] / counts[i]).cast<float>();
    return out;
}

}  // namespace certislam::slam
