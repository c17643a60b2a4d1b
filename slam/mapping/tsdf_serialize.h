// A TSDF's lossless compressed bytes (OpenVDB stream, blosc) and voxel-exact comparison
// (private to tsdf*.cpp: TsdfVolume::Serialize, Deserialize and SameVoxels call them).
#pragma once

#include <memory>
#include <string>
#include <string_view>

#include "slam/mapping/tsdf.h"

namespace certislam::slam {

/// True when both hold the same voxels with bit-identical values and settings.
bool SameTsdfVoxels(const TsdfVolume::Impl& a, const TsdfVolume::Impl& b);

/// The grids and settings of `impl` as bytes: a fixed little-endian header, then the grids.
std::string SerializeTsdf(const TsdfVolume::Impl& impl);

/// Parses SerializeTsdf's bytes. Untrusted input: returns nullptr and sets `*error` (when not
/// null) on failure.
std::unique_ptr<TsdfVolume::Impl> DeserializeTsdf(std::string_view bytes, std::string* error);

}  // namespace certislam::slam
