// One mesh of a team's map from its keyframes and poses.
#include "slam/mapping/keyframe_fusion.h"

#include "slam/mapping/tsdf.h"

namespace certislam::slam {

TriangleMesh FuseKeyframes(const std::vector<std::vector<Keyframe>>& robots,
                           const std::vector<Trajectory>& trajectories, double voxel_m,
                           const FusionProgress& progress) {
    TsdfConfig config;
    config.voxel_size_m = voxel_m;
    TsdfVolume volume(config);
    int total = 0, done = 0;
    for (const auto& robot : robots) total += static_cast<int>(robot.size());
    for (size_t r = 0; r < robots.size(); ++r) {
        for (size_t i = 0; i < robots[r].size() && i < trajectories[r].size(); ++i) {
            volume.Integrate(*robots[r][i].cloud, trajectories[r][i].T_world_body);
            ++done;
            if (progress) progress(static_cast<double>(done) / total);
        }
    }
    return volume.ExtractMesh();
}

}  // namespace certislam::slam
