// Voxel-grid downsampling: hash of integer voxel coordinates -> running centroid.
#include "slam/frontend/downsample.h"

#include <cmath>
#include <cstdint>
#include <unordered_map>

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
    std::unordered_map<std::uint64_t, std::uint32_t> slot;
    slot.reserve(cloud.size() / 2 + 1);
    std::vector<Eigen::Vector3d> sums;
    std::vector<std::uint32_t> counts;
    for (const Eigen::Vector3f& p : cloud) {
        if (!p.allFinite()) continue;
        const auto [it, inserted] =
            slot.try_emplace(key(p), static_cast<std::uint32_t>(sums.size()));
        if (inserted) {
            sums.emplace_back(Eigen::Vector3d::Zero());
            counts.push_back(0);
        }
        sums[it->second] += p.cast<double>();
        ++counts[it->second];
    }
    PointCloud out(sums.size());
    for (std::size_t i = 0; i < sums.size(); ++i) out[i] = (sums[i] / counts[i]).cast<float>();
    return out;
}

}  // namespace certislam::slam
