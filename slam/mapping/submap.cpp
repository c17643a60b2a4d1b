// TsdfMap: submap creation, integration relative to the anchor, re-anchoring, meshing, fusion;
// a submap's bytes.
#include "slam/mapping/submap.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <utility>

namespace certislam::slam {

void TsdfMapConfig::Validate() const {
    tsdf.Validate();
    if (!(submap_distance_m > 0.0 && submap_distance_m <= 1000.0)) {
        throw std::invalid_argument("TsdfMapConfig.submap_distance_m = " +
                                    std::to_string(submap_distance_m) + ": must be in (0, 1000]");
    }
    if (!(memory_budget_mb >= 0.0)) {
        throw std::invalid_argument("TsdfMapConfig.memory_budget_mb = " +
                                    std::to_string(memory_budget_mb) + ": must be >= 0");
    }
    if (max_coarsening < 0 || max_coarsening > 6) {
        throw std::invalid_argument("TsdfMapConfig.max_coarsening = " +
                                    std::to_string(max_coarsening) + ": must be in [0, 6]");
    }
    if (submap_max_keyframes < 0) {
        throw std::invalid_argument("TsdfMapConfig.submap_max_keyframes = " +
                                    std::to_string(submap_max_keyframes) + ": must be >= 0");
    }
}

TsdfMap::TsdfMap(int robot, const TsdfMapConfig& config) : robot_(robot), config_(config) {
    config_.Validate();
    budget_.voxel_size_m = config_.tsdf.voxel_size_m;
}

TsdfMapBudget TsdfMap::Budget() const {
    TsdfMapBudget budget = budget_;
    for (const std::size_t bytes : memory_) budget.memory_bytes += bytes;
    return budget;
}

bool TsdfMap::OverBudget() {
    const double budget_bytes = config_.memory_budget_mb * 1024.0 * 1024.0;
    if (budget_bytes <= 0.0 || static_cast<double>(Budget().memory_bytes) <= budget_bytes) {
        return false;
    }
    constexpr double kLargestVoxel = 5.0;  // TsdfConfig::Validate's upper limit
    if (budget_.coarsenings >= config_.max_coarsening ||
        budget_.voxel_size_m * 2.0 > kLargestVoxel) {
        ++budget_.skipped_scans;
        return true;
    }
    // Eight times fewer voxels per volume for each doubling; existing submaps are kept as they are.
    ++budget_.coarsenings;
    budget_.voxel_size_m *= 2.0;
    CloseActive();
    return false;
}

void TsdfMap::CloseActive() {
    if (!active_) return;
    const std::size_t i = *active_;
    active_.reset();
    if (!config_.pack_closed_submaps) return;
    submaps_[i].volume.Pack();  // its mesh, if cached, stays valid
    memory_[i] = submaps_[i].volume.Stats().memory_bytes;
}

TsdfMapInsertResult TsdfMap::Insert(int keyframe, const Eigen::Isometry3d& T_world_sensor,
                                    const PointCloud& cloud) {
    TsdfMapInsertResult result;
    if (OverBudget()) {
        result.status = TsdfMapInsertResult::Status::kOverBudget;
        return result;
    }
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
        TsdfConfig tsdf = config_.tsdf;
        tsdf.voxel_size_m = budget_.voxel_size_m;
        TsdfVolume volume(tsdf);
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
        memory_.push_back(submaps_.back().volume.Stats().memory_bytes);
        CloseActive();
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
    memory_[*active_] = a.volume.Stats().memory_bytes;
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
    if (config_.pack_closed_submaps) submap.volume.Pack();  // only received and re-posed
    for (std::size_t i = 0; i < submaps_.size(); ++i) {
        if (submaps_[i].id == submap.id) {
            submaps_[i] = std::move(submap);
            mesh_[i].reset();
            memory_[i] = submaps_[i].volume.Stats().memory_bytes;
            if (active_ == i) active_.reset();
            return;
        }
    }
    submaps_.push_back(std::move(submap));
    mesh_.emplace_back();
    memory_.push_back(submaps_.back().volume.Stats().memory_bytes);
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

TriangleMesh TsdfMap::FusedMesh(const TsdfConfig& config, int pieces,
                                const TsdfVolume::RunPieces& run) const {
    std::vector<TsdfVolume::FusePart> parts;
    for (const Submap& s : submaps_) parts.push_back({&s.volume, s.T_world_submap});
    return TsdfVolume::FuseAndMesh(parts, config, 8, pieces, run);
}

// Submap bytes: a fixed little-endian header (ids, anchor pose, keyframes) + the TSDF stream.
namespace {

static_assert(std::endian::native == std::endian::little, "the byte format is little-endian");

constexpr char kMagic[8] = {'C', 'S', 'S', 'U', 'B', 'M', '0', '1'};
constexpr std::uint32_t kMaxKeyframes = 1u << 24;  // far above any mission; bounds allocation
constexpr double kRotationTolerance = 1e-6;        // |R^T R - I| and |det R - 1| on input

struct Header {
    char magic[8];
    std::int32_t robot, index, anchor_robot, anchor_index;
    double rotation[9];     // row-major
    double translation[3];  // metres
    std::uint32_t keyframe_count;
    std::uint32_t reserved;
};

}  // namespace

std::string SerializeSubmap(const Submap& submap, int sdf_bits) {
    Header h{};
    std::memcpy(h.magic, kMagic, sizeof kMagic);
    h.robot = submap.id.robot;
    h.index = submap.id.index;
    h.anchor_robot = submap.anchor.robot;
    h.anchor_index = submap.anchor.index;
    const Eigen::Matrix3d R = submap.T_world_submap.rotation();
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) h.rotation[3 * r + c] = R(r, c);
        h.translation[r] = submap.T_world_submap.translation()[r];
    }
    h.keyframe_count = static_cast<std::uint32_t>(submap.keyframes.size());
    std::string out(sizeof h, '\0');
    std::memcpy(out.data(), &h, sizeof h);
    for (int k : submap.keyframes) {
        const std::int32_t v = k;
        out.append(reinterpret_cast<const char*>(&v), sizeof v);
    }
    return out + submap.volume.Serialize(sdf_bits);
}

std::optional<Submap> DeserializeSubmap(std::string_view bytes, std::string* error, bool packed) {
    auto fail = [&](const std::string& what) {
        if (error != nullptr) *error = "submap bytes: " + what;
        return std::nullopt;
    };
    Header h;
    if (bytes.size() < sizeof h) return fail("truncated header");
    std::memcpy(&h, bytes.data(), sizeof h);
    if (std::memcmp(h.magic, kMagic, sizeof kMagic) != 0) return fail("bad magic");
    if (h.keyframe_count > kMaxKeyframes ||
        bytes.size() - sizeof h < std::size_t{h.keyframe_count} * sizeof(std::int32_t)) {
        return fail("keyframe list longer than the bytes");
    }
    Eigen::Matrix3d R;
    Eigen::Vector3d t;
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) R(r, c) = h.rotation[3 * r + c];
        t[r] = h.translation[r];
    }
    if (!R.allFinite() || !t.allFinite() ||
        (R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > kRotationTolerance ||
        std::abs(R.determinant() - 1.0) > kRotationTolerance) {
        return fail("anchor pose is not a rigid transform");
    }
    std::vector<int> keyframes(h.keyframe_count);
    const char* p = bytes.data() + sizeof h;
    for (auto& k : keyframes) {
        std::int32_t v;
        std::memcpy(&v, p, sizeof v);
        k = v;
        p += sizeof v;
    }
    std::string volume_error;
    const std::string_view volume_bytes = bytes.substr(static_cast<std::size_t>(p - bytes.data()));
    auto volume = packed ? TsdfVolume::DeserializePacked(volume_bytes, &volume_error)
                         : TsdfVolume::Deserialize(volume_bytes, &volume_error);
    if (!volume) return fail(volume_error);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = R;
    T.translation() = t;
    return Submap{SubmapId{h.robot, h.index}, PoseId{h.anchor_robot, h.anchor_index}, T,
                  std::move(keyframes), std::move(*volume)};
}

}  // namespace certislam::slam
