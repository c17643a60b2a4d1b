// A TSDF's bytes in a checked voxel format of our own (tsdf_serialize.h) and voxel-exact
// comparison. The reader is for untrusted input: every count is checked against the bytes left
// before anything is allocated, every value and origin before a grid is built.
#include "slam/mapping/tsdf_serialize.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <vector>

#include "slam/core/check.h"
#include "slam/mapping/tsdf_impl.h"

namespace certislam::slam {
namespace {

static_assert(std::endian::native == std::endian::little, "the byte format is little-endian");

using Leaf = openvdb::FloatGrid::TreeType::LeafNodeType;
using Mask = std::array<std::uint64_t, kTsdfMaskWords>;
static_assert(Leaf::DIM == 8 && Leaf::SIZE == 64 * kTsdfMaskWords);

constexpr char kMagic[8] = {'C', 'S', 'T', 'S', 'D', 'F', '0', '3'};

// The settings as a fixed little-endian header (the voxels carry no TsdfConfig).
struct Header {
    char magic[8];
    double voxel_size_m, truncation_voxels, behind_surface_voxels, ray_radius_voxels;
    double min_range_m, max_range_m;
    float max_weight, min_mesh_weight;
    std::uint32_t group_points_by_voxel;
    std::uint32_t weight_dropoff;
    std::uint64_t voxel_bytes;  ///< the bytes after the header
};
static_assert(sizeof(Header) == kTsdfHeaderBytes);

bool SameConfig(const TsdfConfig& a, const TsdfConfig& b) {
    return a.voxel_size_m == b.voxel_size_m && a.truncation_voxels == b.truncation_voxels &&
           a.behind_surface_voxels == b.behind_surface_voxels &&
           a.ray_radius_voxels == b.ray_radius_voxels && a.min_range_m == b.min_range_m &&
           a.max_range_m == b.max_range_m && a.max_weight == b.max_weight &&
           a.min_mesh_weight == b.min_mesh_weight &&
           a.group_points_by_voxel == b.group_points_by_voxel &&
           a.weight_dropoff == b.weight_dropoff;
}

// True when every active voxel of `a` is active in `b` with the same distance and weight.
bool Contains(const TsdfVolume::Impl& a, const TsdfVolume::Impl& b) {
    const auto b_w = b.weight->getConstAccessor();
    const auto b_s = b.sdf->getConstAccessor();
    const auto a_s = a.sdf->getConstAccessor();
    for (auto it = a.weight->cbeginValueOn(); it; ++it) {
        const openvdb::Coord ijk = it.getCoord();
        if (!b_w.isValueOn(ijk) || b_w.getValue(ijk) != *it ||
            b_s.getValue(ijk) != a_s.getValue(ijk)) {
            return false;
        }
    }
    return true;
}

Header HeaderOf(const TsdfConfig& c) {
    Header h{};
    std::memcpy(h.magic, kMagic, sizeof kMagic);
    h.voxel_size_m = c.voxel_size_m;
    h.truncation_voxels = c.truncation_voxels;
    h.behind_surface_voxels = c.behind_surface_voxels;
    h.ray_radius_voxels = c.ray_radius_voxels;
    h.min_range_m = c.min_range_m;
    h.max_range_m = c.max_range_m;
    h.max_weight = c.max_weight;
    h.min_mesh_weight = c.min_mesh_weight;
    h.group_points_by_voxel = c.group_points_by_voxel ? 1 : 0;
    h.weight_dropoff = c.weight_dropoff ? 1 : 0;
    return h;
}

TsdfConfig ConfigOf(const Header& h) {
    TsdfConfig c;
    c.voxel_size_m = h.voxel_size_m;
    c.truncation_voxels = h.truncation_voxels;
    c.behind_surface_voxels = h.behind_surface_voxels;
    c.ray_radius_voxels = h.ray_radius_voxels;
    c.min_range_m = h.min_range_m;
    c.max_range_m = h.max_range_m;
    c.max_weight = h.max_weight;
    c.min_mesh_weight = h.min_mesh_weight;
    c.group_points_by_voxel = h.group_points_by_voxel != 0;
    c.weight_dropoff = h.weight_dropoff != 0;
    return c;
}

template <typename T>
void Append(std::string& out, const T& v) {
    out.append(reinterpret_cast<const char*>(&v), sizeof v);
}

// Floats stored byte-plane by byte-plane (all first bytes, then all second bytes, ...): the
// exponent bytes of a smooth field repeat, which zstd finds (blosc's "shuffle" filter).
void AppendShuffled(std::string& out, const std::vector<float>& values) {
    const std::size_t n = values.size();
    const std::size_t base = out.size();
    out.resize(base + 4 * n);
    const auto* src = reinterpret_cast<const unsigned char*>(values.data());
    for (std::size_t b = 0; b < 4; ++b) {
        for (std::size_t i = 0; i < n; ++i) out[base + b * n + i] = char(src[4 * i + b]);
    }
}

std::vector<float> ReadShuffled(const char* in, std::size_t n) {
    std::vector<float> values(n);
    auto* dst = reinterpret_cast<unsigned char*>(values.data());
    for (std::size_t b = 0; b < 4; ++b) {
        for (std::size_t i = 0; i < n; ++i)
            dst[4 * i + b] = static_cast<unsigned char>(in[b * n + i]);
    }
    return values;
}

// A bounded cursor over untrusted bytes; a refusal names the byte offset and the rule.
class Reader {
  public:
    explicit Reader(std::string_view bytes) : bytes_(bytes) {}
    std::size_t offset() const { return pos_; }
    std::size_t left() const { return bytes_.size() - pos_; }
    const char* here() const { return bytes_.data() + pos_; }
    void Skip(std::size_t n) { pos_ += n; }  // callers checked n <= left()
    template <typename T>
    T Take() {
        T v;
        std::memcpy(&v, here(), sizeof v);
        pos_ += sizeof v;
        return v;
    }

  private:
    std::string_view bytes_;
    std::size_t pos_ = 0;
};

std::string At(std::size_t offset, const std::string& rule) {
    return "byte offset " + std::to_string(offset) + ": " + rule;
}

// Distinct values of `origins` rounded down to multiples of `node_voxels` (a power of two).
std::size_t DistinctNodes(const std::vector<openvdb::Coord>& origins, std::int32_t node_voxels) {
    std::vector<openvdb::Coord> nodes;
    nodes.reserve(origins.size());
    for (const openvdb::Coord& o : origins) nodes.push_back(o & ~(node_voxels - 1));
    std::sort(nodes.begin(), nodes.end());
    return std::size_t(std::unique(nodes.begin(), nodes.end()) - nodes.begin());
}

// Unique origins whose tree nodes stay few: OpenVDB allocates a 128^3-voxel node (33 KiB) and a
// 4096^3-voxel node (264 KiB) above each scattered leaf. A mapped surface clusters its leaves
// (tens per 128^3 node, the 8 octant nodes at the top), so hostile bytes cannot make a few bytes
// a leaf cost hundreds of KiB. Returns "" or the refusal at `at`, the first origin's offset.
std::string CheckOriginSet(const std::vector<openvdb::Coord>& origins, std::size_t at) {
    std::vector<openvdb::Coord> sorted = origins;
    std::sort(sorted.begin(), sorted.end());
    const auto dup = std::adjacent_find(sorted.begin(), sorted.end());
    if (dup != sorted.end()) {  // named at its second occurrence
        const auto first = std::find(origins.begin(), origins.end(), *dup);
        const auto l = std::size_t(std::find(first + 1, origins.end(), *dup) - origins.begin());
        return At(at + 12 * l, "duplicate leaf origin (" + std::to_string(dup->x()) + ", " +
                                   std::to_string(dup->y()) + ", " + std::to_string(dup->z()) +
                                   ")");
    }
    const std::size_t n = origins.size();
    for (const auto& [voxels, per] :
         {std::pair<std::int32_t, std::size_t>{128, kTsdfLeavesPerMidNode},
          {4096, kTsdfLeavesPerTopNode}}) {
        const std::size_t nodes = DistinctNodes(origins, voxels);
        if (nodes > 8 + n / per) {
            return At(at, std::to_string(n) + " leaves spread over " + std::to_string(nodes) +
                              " tree nodes of " + std::to_string(voxels) +
                              "^3 voxels: at most 8 + " + std::to_string(n) + "/" +
                              std::to_string(per));
        }
    }
    return "";
}

// The leaves' origins and active masks, checked: each origin a multiple of the leaf size, within
// kTsdfMaxOriginVoxels (CheckOriginSet's rules on the set); each mask with an active voxel.
// Returns "" or the refusal.
std::string ReadLeaves(Reader& in, std::size_t count, std::vector<openvdb::Coord>* origins,
                       std::vector<Mask>* masks, std::size_t* active) {
    origins->reserve(count);
    const std::size_t origins_at = in.offset();
    for (std::size_t l = 0; l < count; ++l) {
        const std::size_t at = in.offset();
        std::array<std::int32_t, 3> o;
        for (auto& v : o) v = in.Take<std::int32_t>();
        for (const std::int32_t v : o) {
            if (v % std::int32_t(Leaf::DIM) != 0) {
                return At(at, "leaf origin " + std::to_string(v) + " is not a multiple of 8");
            }
            if (v < -kTsdfMaxOriginVoxels || v > kTsdfMaxOriginVoxels) {
                return At(at, "leaf origin " + std::to_string(v) + " beyond +-" +
                                  std::to_string(kTsdfMaxOriginVoxels) + " voxels");
            }
        }
        origins->emplace_back(o[0], o[1], o[2]);
    }
    if (std::string e = CheckOriginSet(*origins, origins_at); !e.empty()) return e;
    masks->resize(count);
    *active = 0;
    for (Mask& m : *masks) {
        const std::size_t at = in.offset();
        std::size_t on = 0;
        for (auto& w : m) on += std::size_t(std::popcount(w = in.Take<std::uint64_t>()));
        if (on == 0) return At(at, "leaf mask has no active voxel");
        *active += on;  // <= 512 per leaf, and count was bounded by the bytes
    }
    return "";
}

// Distances finite; weights finite, in [0, max_weight]. Returns "" or the refusal.
std::string CheckValues(const std::vector<float>& sdf, const std::vector<float>& weight,
                        float max_weight, std::size_t sdf_at) {
    const std::size_t n = sdf.size();
    for (std::size_t i = 0; i < n; ++i) {
        if (!std::isfinite(sdf[i])) {
            return At(sdf_at, "distance of active voxel " + std::to_string(i) + " is not finite");
        }
        if (!(weight[i] >= 0.0f && weight[i] <= max_weight)) {
            return At(sdf_at + 4 * n, "weight of active voxel " + std::to_string(i) + " = " +
                                          std::to_string(weight[i]) + ": must be in [0, " +
                                          std::to_string(max_weight) + "]");
        }
    }
    return "";
}

// Builds the grids of checked leaves: inactive voxels keep the backgrounds, as when integrated.
void BuildGrids(TsdfVolume::Impl& impl, const TsdfVoxelList& list) {
    const float sdf_background = impl.sdf->background();
    std::size_t v = 0;
    for (std::size_t l = 0; l < list.origins.size(); ++l) {
        auto s_leaf = std::make_unique<Leaf>(list.origins[l], sdf_background, false);
        auto w_leaf = std::make_unique<Leaf>(list.origins[l], 0.0f, false);
        for (openvdb::Index i = 0; i < Leaf::SIZE; ++i) {
            if ((list.masks[l][i >> 6] >> (i & 63) & 1) == 0) continue;
            s_leaf->setValueOn(i, list.sdf[v]);
            w_leaf->setValueOn(i, list.weight[v]);
            ++v;
        }
        impl.sdf->tree().addLeaf(s_leaf.release());
        impl.weight->tree().addLeaf(w_leaf.release());
    }
}

// The voxels after the header (tsdf_serialize.h's layout) into `impl`. Returns "" or the refusal.
std::string ReadVoxels(Reader& in, TsdfVoxelList& list) {
    if (in.left() < sizeof(std::uint64_t)) return At(in.offset(), "truncated leaf count");
    const std::size_t count_at = in.offset();
    const std::uint64_t count = in.Take<std::uint64_t>();
    if (count > in.left() / kTsdfMinLeafBytes) {
        return At(count_at, "leaf count " + std::to_string(count) + " needs at least " +
                                std::to_string(kTsdfMinLeafBytes) + " bytes a leaf, " +
                                std::to_string(in.left()) + " left");
    }
    std::size_t active = 0;
    if (std::string e = ReadLeaves(in, count, &list.origins, &list.masks, &active); !e.empty()) {
        return e;
    }
    if (in.left() / 8 < active || in.left() != 8 * active) {
        return At(in.offset(), std::to_string(active) + " active voxels need " +
                                   std::to_string(8 * active) + " bytes of values, length " +
                                   std::to_string(in.left()) + " left");
    }
    const std::size_t sdf_at = in.offset();
    list.sdf = ReadShuffled(in.here(), active);
    in.Skip(4 * active);
    list.weight = ReadShuffled(in.here(), active);
    in.Skip(4 * active);
    return CheckValues(list.sdf, list.weight, list.config.max_weight, sdf_at);
}

}  // namespace

bool SameTsdfVoxels(const TsdfVolume::Impl& a, const TsdfVolume::Impl& b) {
    return SameConfig(a.config, b.config) &&
           a.weight->activeVoxelCount() == b.weight->activeVoxelCount() && Contains(a, b);
}

std::string SerializeTsdf(const TsdfVolume::Impl& impl) {
    std::vector<const Leaf*> w_leaves, s_leaves;
    for (auto it = impl.weight->tree().cbeginLeaf(); it; ++it) {
        if (it->isEmpty()) continue;  // no active voxel: nothing observed (never made so)
        w_leaves.push_back(&*it);
        s_leaves.push_back(impl.sdf->tree().probeConstLeaf(it->origin()));
        CERTISLAM_CHECK(s_leaves.back() != nullptr);  // both grids are touched together
    }
    std::string voxels;
    Append(voxels, std::uint64_t{w_leaves.size()});
    for (const Leaf* leaf : w_leaves) {
        for (int a = 0; a < 3; ++a) Append(voxels, std::int32_t{leaf->origin()[a]});
    }
    std::vector<float> sdf, weight;
    for (std::size_t l = 0; l < w_leaves.size(); ++l) {
        const auto& mask = w_leaves[l]->getValueMask();
        for (openvdb::Index w = 0; w < kTsdfMaskWords; ++w) {
            Append(voxels, mask.getWord<std::uint64_t>(w));
        }
        for (auto on = mask.beginOn(); on; ++on) {
            sdf.push_back(s_leaves[l]->getValue(on.pos()));
            weight.push_back(w_leaves[l]->getValue(on.pos()));
        }
    }
    AppendShuffled(voxels, sdf);
    AppendShuffled(voxels, weight);
    Header h = HeaderOf(impl.config);
    h.voxel_bytes = voxels.size();
    std::string out(sizeof h, '\0');
    std::memcpy(out.data(), &h, sizeof h);
    return out + voxels;
}

std::optional<TsdfVoxelList> DecodeTsdfVoxels(std::string_view bytes, std::string* error) {
    auto fail = [&](const std::string& what) {
        if (error != nullptr) *error = "TSDF bytes: " + what;
        return std::optional<TsdfVoxelList>();
    };
    Header h;
    if (bytes.size() < sizeof h) return fail(At(bytes.size(), "truncated header"));
    std::memcpy(&h, bytes.data(), sizeof h);
    if (std::memcmp(h.magic, kMagic, sizeof kMagic) != 0) return fail(At(0, "bad magic"));
    if (h.voxel_bytes != bytes.size() - sizeof h) {
        return fail(At(offsetof(Header, voxel_bytes),
                       "voxel length " + std::to_string(h.voxel_bytes) + " does not match the " +
                           std::to_string(bytes.size() - sizeof h) + " bytes after the header"));
    }
    if (!std::isfinite(h.max_weight) || !std::isfinite(h.min_mesh_weight)) {
        return fail(At(offsetof(Header, max_weight), "weight settings are not finite"));
    }
    TsdfVoxelList list;
    list.config = ConfigOf(h);
    try {
        list.config.Validate();
    } catch (const std::invalid_argument& e) {
        return fail(At(0, std::string("header settings: ") + e.what()));
    }
    Reader in(bytes);
    in.Skip(sizeof h);
    if (std::string e = ReadVoxels(in, list); !e.empty()) return fail(e);
    return list;
}

std::unique_ptr<TsdfVolume::Impl> DeserializeTsdf(std::string_view bytes, std::string* error) {
    const std::optional<TsdfVoxelList> list = DecodeTsdfVoxels(bytes, error);
    if (!list) return nullptr;
    auto impl = std::make_unique<TsdfVolume::Impl>(list->config);
    BuildGrids(*impl, *list);
    impl->MarkAllDirty();
    return impl;
}

}  // namespace certislam::slam
