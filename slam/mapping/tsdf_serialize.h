// A TSDF's lossless bytes in a checked voxel format of our own, and voxel-exact comparison
// (private to tsdf*.cpp: TsdfVolume::Serialize, Deserialize and SameVoxels call them).
//
// Layout, little-endian: an 80-byte header (magic "CSTSDF03", the TsdfConfig, the length of
// the rest), then the leaf count L (uint64), L leaf origins (3 x int32, multiples of 8), L
// active masks (8 x uint64; bit i of word w is voxel 64 w + i of the 8^3 leaf, x-major), then
// the distances and then the weights of the A active voxels in leaf and mask order (A float32
// each, stored byte-plane by byte-plane). Inactive voxels hold the backgrounds.
//
// The quantised layout (magic "CSTSDFQ3", what a mapper sends its peers) has the same header and
// then: the distance bits b (uint32, 8 or 16), the distance step and the weight step (float32
// each), the leaves as above, the A distances as signed b-bit multiples of the distance step
// (byte-planed) and the A weights as uint8 multiples of the weight step. Quantisation moves a
// value by at most half its step; a voxel with weight > 0 keeps a weight > 0.
#pragma once

#include <array>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "slam/mapping/tsdf_impl.h"

namespace certislam::slam {

inline constexpr std::size_t kTsdfHeaderBytes = 80;  ///< the fixed header
inline constexpr std::size_t kTsdfMaskWords = 8;     ///< 64-bit words of a leaf's active mask
/// A leaf's least bytes before its values: origin and mask.
inline constexpr std::size_t kTsdfLeafBytes = 12 + 8 * kTsdfMaskWords;
/// Leaf origins beyond this many voxels from the volume's origin are refused (2^24: 168 km at
/// the smallest voxel, 0.01 m).
inline constexpr std::int32_t kTsdfMaxOriginVoxels = 1 << 24;
/// At most 8 + L / this nodes of 128^3 voxels above L leaves (a mapped surface puts tens of
/// leaves in each).
inline constexpr std::size_t kTsdfLeavesPerMidNode = 8;
/// At most 8 + L / this nodes of 4096^3 voxels above L leaves (a submap: the 8 octants).
inline constexpr std::size_t kTsdfLeavesPerTopNode = 64;

/// The active voxels of a TSDF as its bytes hold them (no grids: a few bytes a voxel).
struct TsdfVoxelList {
    TsdfConfig config;                    ///< the volume's settings
    std::vector<openvdb::Coord> origins;  ///< leaf origins, in the bytes' order
    std::vector<std::array<std::uint64_t, kTsdfMaskWords>> masks;  ///< active masks, by leaf
    std::vector<float> sdf, weight;  ///< active voxels' values, leaf by leaf in mask order

    /// Calls f(ijk, sdf, weight) for every active voxel, in the order of a grid's ValueOn walk.
    template <typename F>
    void ForEach(F&& f) const {
        ForEachIn([](const openvdb::Coord&) { return true; }, f);
    }

    /// The same for the voxels of the leaves whose origin `keep_leaf` keeps.
    template <typename Keep, typename F>
    void ForEachIn(Keep&& keep_leaf, F&& f) const {
        std::size_t v = 0;
        for (std::size_t l = 0; l < origins.size(); ++l) {
            if (!keep_leaf(origins[l])) {
                for (const std::uint64_t word : masks[l]) v += std::popcount(word);
                continue;
            }
            for (int i = 0; i < 512; ++i) {
                if ((masks[l][i >> 6] >> (i & 63) & 1) == 0) continue;
                f(origins[l].offsetBy(i >> 6, (i >> 3) & 7, i & 7), sdf[v], weight[v]);
                ++v;
            }
        }
    }
};

/// True when both hold the same voxels with bit-identical values and settings.
bool SameTsdfVoxels(const TsdfVolume::Impl& a, const TsdfVolume::Impl& b);

/// The grids and settings of `impl` as bytes: sdf_bits 32, the lossless layout; 16 or 8, the
/// quantised one (steps: the largest |distance| over 2^(b-1) - 1, the largest weight over 255).
std::string SerializeTsdf(const TsdfVolume::Impl& impl, int sdf_bits = 32);

/// True when `bytes` start with the lossless layout's magic.
bool IsLosslessTsdfBytes(std::string_view bytes);

/// Parses SerializeTsdf's bytes. Untrusted input: every count is checked against the bytes left
/// before allocating, every value (finite; weight in [0, max_weight]) and origin (aligned,
/// bounded, unique, clustered; an active voxel in every leaf) before building; returns nullptr and
/// sets
/// `*error` (when not null) to the byte offset and the rule on failure.
std::unique_ptr<TsdfVolume::Impl> DeserializeTsdf(std::string_view bytes, std::string* error);

/// DeserializeTsdf's checks, without building grids: the voxel list, or nullopt and `*error`.
std::optional<TsdfVoxelList> DecodeTsdfVoxels(std::string_view bytes, std::string* error);

}  // namespace certislam::slam
