// Scan Context descriptors <-> protobuf: sizes and finiteness checked before bytes are trusted.
#include "actors/convert_descriptor.h"

#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "slam/frontend/scan_context_compression.h"

namespace certislam::actors {
namespace {

bool AllFinite(const auto& values) {
    for (const auto v : values) {
        if (!std::isfinite(v)) return false;
    }
    return true;
}

}  // namespace

v1::ScanContextDescriptor ToProto(const slam::ScanContext& descriptor, const slam::PoseId& id,
                                  DescriptorWire wire) {
    v1::ScanContextDescriptor out;
    *out.mutable_pose_id() = ToProto(id);
    out.set_num_rings(static_cast<std::uint32_t>(descriptor.bins.rows()));
    out.set_num_sectors(static_cast<std::uint32_t>(descriptor.bins.cols()));
    out.set_max_range_m(static_cast<float>(descriptor.max_range_m));
    if (wire == DescriptorWire::kCompact) {
        const std::vector<std::uint8_t> bytes = slam::EncodeScanContextCompact(descriptor);
        out.set_compact(bytes.data(), bytes.size());
        return out;
    }
    out.mutable_values()->Assign(descriptor.bins.data(),
                                 descriptor.bins.data() + descriptor.bins.size());
    out.mutable_ring_key()->Assign(descriptor.ring_key.data(),
                                   descriptor.ring_key.data() + descriptor.ring_key.size());
    return out;
}

std::optional<slam::ScanContext> FromProto(const v1::ScanContextDescriptor& descriptor) {
    const std::uint32_t rings = descriptor.num_rings();
    const std::uint32_t sectors = descriptor.num_sectors();
    if (rings < 1 || rings > 1024 || sectors < 2 || sectors > 4096) return std::nullopt;
    if (!descriptor.compact().empty()) {
        const std::string& packed = descriptor.compact();
        auto decoded =
            slam::DecodeScanContextCompact(std::vector<std::uint8_t>(packed.begin(), packed.end()));
        if (!decoded || decoded->bins.rows() != static_cast<Eigen::Index>(rings) ||
            decoded->bins.cols() != static_cast<Eigen::Index>(sectors) ||
            !decoded->bins.allFinite()) {
            return std::nullopt;
        }
        return decoded;
    }
    if (static_cast<std::uint64_t>(descriptor.values_size()) != std::uint64_t{rings} * sectors ||
        static_cast<std::uint32_t>(descriptor.ring_key_size()) != rings) {
        return std::nullopt;
    }
    if (!AllFinite(descriptor.values()) || !AllFinite(descriptor.ring_key()) ||
        !(descriptor.max_range_m() > 0.0f) || !std::isfinite(descriptor.max_range_m())) {
        return std::nullopt;
    }
    slam::ScanContext out;
    out.bins =
        Eigen::Map<const slam::ScanContextMatrix>(descriptor.values().data(), rings, sectors);
    out.ring_key = Eigen::Map<const Eigen::VectorXf>(descriptor.ring_key().data(), rings);
    out.sector_key = out.bins.colwise().mean().transpose();
    out.max_range_m = descriptor.max_range_m();
    return out;
}

}  // namespace certislam::actors
