// Submap bytes: a fixed little-endian header (ids, anchor pose, keyframes) + the TSDF stream.
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>

#include "slam/mapping/submap.h"

namespace certislam::slam {
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

std::string SerializeSubmap(const Submap& submap) {
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
    return out + submap.volume.Serialize();
}

std::optional<Submap> DeserializeSubmap(std::string_view bytes, std::string* error) {
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
    auto volume = TsdfVolume::Deserialize(bytes.substr(static_cast<std::size_t>(p - bytes.data())),
                                          &volume_error);
    if (!volume) return fail(volume_error);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = R;
    T.translation() = t;
    return Submap{SubmapId{h.robot, h.index}, PoseId{h.anchor_robot, h.anchor_index}, T,
                  std::move(keyframes), std::move(*volume)};
}

}  // namespace certislam::slam
