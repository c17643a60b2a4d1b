// TsdfMap: submap creation, integration relative to the anchor, re-anchoring, meshing, fusion.
#include "slam/mapping/submap.h"

#include <algorithm>
#include <stdexcept>
#include <utility>

namespace certislam::slam {

void TsdfMapConfig::Validate() const {
    tsdf.Validate();
    if (!(submap_distance_m > 0.0 && submap_distance_m <= 1000.0)) {
        throw std::invalid_argument("TsdfMapConfig.submap_distance_m = " +
                                    std::to_string(submap_distance_m) + ": must be in (0, 1000]");
    }
    if (submap_max_keyframes < 0) {
        throw std::invalid_argument("TsdfMapConfig.submap_max_keyframes = " +
                                    std::to_string(submap_max_keyframes) + ": must be >= 0");
    }
}

TsdfMap::TsdfMap(int robot, const TsdfMapConfig& config) : robot_(robot), config_(config) {
    config_.Validate();
}

TsdfMapInsertResult TsdfMap::Insert(int keyframe, const Eigen::Isometry3d& T_world_sensor,
                                    const PointCloud& cloud) {
    TsdfMapInsertResult result;
    bool start = !active_.has_value();
    if (!start) {
        const Submap& a = submaps_[*active_];
        const double moved = (a.T_world_submap.translation() - T_world_sensor.translation()).norm();
        const bool full = config_.submap_max_keyframes > 0 &&
                          static_cast<int>(a.keyframes.size()) >= config_.submap_max_keyframes;
        start = moved > config_.submap_distance_m || full;
    }
    if (start) {
        // Integrate into a fresh volume first, so a scan with no valid rays starts nothing.
        TsdfVolume volume(config_.tsdf);
        result.integrate = volume.Integrate(cloud, Eigen::Isometry3d::Identity());
        if (result.integrate.status != TsdfIntegrateResult::Status::kOk) {
            result.status = TsdfMapInsertResult::Status::kNoValidRays;
            return result;
        }
        int next_index = 0;
        for (const Submap& s : submaps_) {
            if (s.id.robot == robot_) next_index = std::max(next_index, s.id.index + 1);
        }
        submaps_.push_back(Submap{SubmapId{robot_, next_index},
                                  PoseId{robot_, keyframe},
                                  T_world_sensor,
                                  {keyframe},
                                  std::move(volume)});
        mesh_.emplace_back();
        active_ = submaps_.size() - 1;
        result.started_submap = true;
        result.submap = *active_;
        return result;
    }
    Submap& a = submaps_[*active_];
    // Relative to the anchor: the volume stays rigid when the anchor is re-estimated.
    const Eigen::Isometry3d T_submap_sensor = a.T_world_submap.inverse() * T_world_sensor;
    result.integrate = a.volume.Integrate(cloud, T_submap_sensor);
    result.submap = *active_;
    if (result.integrate.status != TsdfIntegrateResult::Status::kOk) {
        result.status = TsdfMapInsertResult::Status::kNoValidRays;
        return result;
    }
    a.keyframes.push_back(keyframe);
    mesh_[*active_].reset();
    return result;
}

std::size_t TsdfMap::Reanchor(
    const std::function<std::optional<Eigen::Isometry3d>(const PoseId&)>& T_world_anchor) {
    std::size_t moved = 0;
    for (Submap& s : submaps_) {
        if (const auto T = T_world_anchor(s.anchor)) {
            s.T_world_submap = *T;
            ++moved;
        }
    }
    return moved;
}

void TsdfMap::AddSubmap(Submap submap) {
    for (std::size_t i = 0; i < submaps_.size(); ++i) {
        if (submaps_[i].id == submap.id) {
            submaps_[i] = std::move(submap);
            mesh_[i].reset();
            if (active_ == i) active_.reset();
            return;
        }
    }
    submaps_.push_back(std::move(submap));
    mesh_.emplace_back();
}

TriangleMesh TsdfMap::ExtractMesh() {
    TriangleMesh world;
    for (std::size_t i = 0; i < submaps_.size(); ++i) {
        if (!mesh_[i]) mesh_[i] = submaps_[i].volume.ExtractMesh();
        AppendMesh(TransformMesh(*mesh_[i], submaps_[i].T_world_submap), &world);
    }
    return world;
}

TsdfVolume TsdfMap::Fuse(const TsdfConfig& config) const {
    TsdfVolume fused(config);
    for (const Submap& s : submaps_) fused.FuseVoxels(s.volume, s.T_world_submap);
    return fused;
}

}  // namespace certislam::slam
