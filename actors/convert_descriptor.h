// Scan Context descriptors on the wire: apart from convert.h so that the back end's actors need
// no front end. The decoder treats its input as untrusted: std::nullopt on anything malformed.
#pragma once

#include <optional>

#include "actors/convert.h"
#include "certislam/v1/scan_context.pb.h"
#include "slam/frontend/scan_context.h"

namespace certislam::actors {

/// How a descriptor travels.
enum class DescriptorWire {
    kFloat32,  ///< every bin and the ring key as float (4.9 kB for 20 x 60)
    kCompact,  ///< slam/frontend/scan_context_compression.h: 5 cm height steps, zstd
};

/// A Scan Context descriptor of keyframe `id` on the wire.
v1::ScanContextDescriptor ToProto(const slam::ScanContext& descriptor, const slam::PoseId& id,
                                  DescriptorWire wire = DescriptorWire::kCompact);
/// The descriptor back (either wire form; keys recomputed); nullopt when sizes disagree with
/// num_rings x num_sectors, the compact bytes do not decode, or values are not finite.
std::optional<slam::ScanContext> FromProto(const v1::ScanContextDescriptor& descriptor);

}  // namespace certislam::actors
