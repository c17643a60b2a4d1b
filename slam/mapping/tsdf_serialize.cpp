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
constexpr char kMagicQuantised[8] = {'C', 'S', 'T', 'S', 'D', 'F', 'Q', '3'};
constexpr int kWeightLevels = 255;  // a quantised weight is one byte

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
                        float max_weight, std::size_t sdf_at, std::size_t sdf_bytes) {
    const std::size_t n = sdf.size();
    for (std::size_t i = 0; i < n; ++i) {
        if (!std::isfinite(sdf[i])) {
            return At(sdf_at, "distance of active voxel " + std::to_string(i) + " is not finite");
        }
        if (!(weight[i] >= 0.0f && weight[i] <= max_weight)) {
            return At(sdf_at + sdf_bytes * n, "weight of active voxel " + std::to_string(i) +
                                                  " = " + std::to_string(weight[i]) +
                                                  ": must be in [0, " + std::to_string(max_weight) +
                                                  "]");
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

// Quantised values: distances as signed `bits`-bit multiples of sdf_step (byte-planed), then
// weights as one-byte multiples of weight_step (tsdf_serialize.h). Returns "" or the refusal.
std::string ReadQuantised(Reader& in, int bits, float sdf_step, float weight_step,
                          std::size_t active, TsdfVoxelList& list) {
    const std::size_t bytes = std::size_t(bits) / 8;
    const std::int32_t qmax = (1 << (bits - 1)) - 1;
    list.sdf.resize(active);
    list.weight.resize(active);
    const auto* p = reinterpret_cast<const unsigned char*>(in.here());
    for (std::size_t i = 0; i < active; ++i) {
        std::uint32_t u = 0;
        for (std::size_t b = 0; b < bytes; ++b) u |= std::uint32_t(p[b * active + i]) << (8 * b);
        const std::int32_t q = bits == 8 ? std::int32_t(std::int8_t(u)) : std::int16_t(u);
        if (q < -qmax) {
            return At(in.offset() + i, "distance of active voxel " + std::to_string(i) + " is " +
                                           std::to_string(q) + " steps: at least -" +
                                           std::to_string(qmax));
        }
        list.sdf[i] = float(q) * sdf_step;
        list.weight[i] = float(p[bytes * active + i]) * weight_step;
    }
    in.Skip((bytes + 1) * active);
    return "";
}

// The voxels after the header (tsdf_serialize.h's layouts) into `list`. Returns "" or the
// refusal.
std::string ReadVoxels(Reader& in, bool quantised, TsdfVoxelList& list) {
    int bits = 32;
    float sdf_step = 0.0f, weight_step = 0.0f;
    if (quantised) {
        if (in.left() < 12) return At(in.offset(), "truncated quantisation settings");
        const std::size_t at = in.offset();
        const std::uint32_t b = in.Take<std::uint32_t>();
        if (b != 8 && b != 16) {
            return At(at, "distance bits " + std::to_string(b) + ": must be 8 or 16");
        }
        bits = int(b);
        sdf_step = in.Take<float>();
        weight_step = in.Take<float>();
        if (!(std::isfinite(sdf_step) && sdf_step >= 0.0f && std::isfinite(weight_step) &&
              weight_step >= 0.0f)) {
            return At(at + 4, "quantisation steps must be finite and >= 0");
        }
    }
    const std::size_t value_bytes = quantised ? std::size_t(bits) / 8 + 1 : 8;
    if (in.left() < sizeof(std::uint64_t)) return At(in.offset(), "truncated leaf count");
    const std::size_t count_at = in.offset();
    const std::uint64_t count = in.Take<std::uint64_t>();
    if (count > in.left() / (kTsdfLeafBytes + value_bytes)) {
        return At(count_at, "leaf count " + std::to_string(count) + " needs at least " +
                                std::to_string(kTsdfLeafBytes + value_bytes) + " bytes a leaf, " +
                                std::to_string(in.left()) + " left");
    }
    std::size_t active = 0;
    if (std::string e = ReadLeaves(in, count, &list.origins, &list.masks, &active); !e.empty()) {
        return e;
    }
    if (in.left() / value_bytes < active || in.left() != value_bytes * active) {
        return At(in.offset(), std::to_string(active) + " active voxels need " +
                                   std::to_string(value_bytes * active) +
                                   " bytes of values, length " + std::to_string(in.left()) +
                                   " left");
    }
    const std::size_t sdf_at = in.offset();
    if (quantised) {
        if (std::string e = ReadQuantised(in, bits, sdf_step, weight_step, active, list);
            !e.empty()) {
            return e;
        }
    } else {
        list.sdf = ReadShuffled(in.here(), active);
        in.Skip(4 * active);
        list.weight = ReadShuffled(in.here(), active);
        in.Skip(4 * active);
    }
    return CheckValues(list.sdf, list.weight, list.config.max_weight, sdf_at,
                       quantised ? std::size_t(bits) / 8 : 4);
}

// The active voxels of `impl` in leaf and mask order (the layouts' order).
TsdfVoxelList CollectVoxels(const TsdfVolume::Impl& impl) {
    TsdfVoxelList list;
    list.config = impl.config;
    for (auto it = impl.weight->tree().cbeginLeaf(); it; ++it) {
        if (it->isEmpty()) continue;  // no active voxel: nothing observed (never made so)
        const Leaf* s_leaf = impl.sdf->tree().probeConstLeaf(it->origin());
        CERTISLAM_CHECK(s_leaf != nullptr);  // both grids are touched together
        list.origins.push_back(it->origin());
        const auto& mask = it->getValueMask();
        Mask& m = list.masks.emplace_back();
        for (openvdb::Index w = 0; w < kTsdfMaskWords; ++w) m[w] = mask.getWord<std::uint64_t>(w);
        for (auto on = mask.beginOn(); on; ++on) {
            list.sdf.push_back(s_leaf->getValue(on.pos()));
            list.weight.push_back(it->getValue(on.pos()));
        }
    }
    return list;
}

void AppendLeaves(std::string& out, const TsdfVoxelList& list) {
    Append(out, std::uint64_t{list.origins.size()});
    for (const openvdb::Coord& o : list.origins) {
        for (int a = 0; a < 3; ++a) Append(out, std::int32_t{o[a]});
    }
    for (const Mask& m : list.masks) {
        for (const std::uint64_t w : m) Append(out, w);
    }
}

float MaxAbs(const std::vector<float>& values) {
    float m = 0.0f;
    for (const float v : values) m = std::max(m, std::abs(v));
    return m;
}

// The quantised layout's voxel section: each value the nearest multiple of its step (a positive
// weight at least one step), the steps chosen so that the largest value fits.
void AppendQuantised(std::string& out, const TsdfVoxelList& list, int bits) {
    const std::int32_t qmax = (1 << (bits - 1)) - 1;
    const float sdf_step = MaxAbs(list.sdf) / float(qmax);
    float weight_step = MaxAbs(list.weight) / float(kWeightLevels);
    while (weight_step * float(kWeightLevels) > list.config.max_weight) {  // a reader's bound
        weight_step = std::nextafter(weight_step, 0.0f);
    }
    Append(out, std::uint32_t(bits));
    Append(out, sdf_step);
    Append(out, weight_step);
    AppendLeaves(out, list);
    const std::size_t n = list.sdf.size(), bytes = std::size_t(bits) / 8, base = out.size();
    out.resize(base + (bytes + 1) * n);
    for (std::size_t i = 0; i < n; ++i) {
        const long q = sdf_step > 0.0f ? std::lround(list.sdf[i] / sdf_step) : 0;
        const auto u = std::uint32_t(std::clamp<long>(q, -qmax, qmax));
        for (std::size_t b = 0; b < bytes; ++b) out[base + b * n + i] = char(u >> (8 * b) & 0xff);
        long w = weight_step > 0.0f ? std::lround(list.weight[i] / weight_step) : 0;
        if (list.weight[i] > 0.0f) w = std::max(w, 1L);
        out[base + bytes * n + i] = char(std::min<long>(w, kWeightLevels));
    }
}

}  // namespace

bool SameTsdfVoxels(const TsdfVolume::Impl& a, const TsdfVolume::Impl& b) {
    return SameConfig(a.config, b.config) &&
           a.weight->activeVoxelCount() == b.weight->activeVoxelCount() && Contains(a, b);
}

std::string SerializeTsdf(const TsdfVolume::Impl& impl, int sdf_bits) {
    CERTISLAM_CHECK(sdf_bits == 8 || sdf_bits == 16 || sdf_bits == 32);
    const TsdfVoxelList list = CollectVoxels(impl);
    std::string voxels;
    if (sdf_bits == 32) {
        AppendLeaves(voxels, list);
        AppendShuffled(voxels, list.sdf);
        AppendShuffled(voxels, list.weight);
    } else {
        AppendQuantised(voxels, list, sdf_bits);
    }
    Header h = HeaderOf(impl.config);
    if (sdf_bits != 32) std::memcpy(h.magic, kMagicQuantised, sizeof kMagicQuantised);
    h.voxel_bytes = voxels.size();
    std::string out(sizeof h, '\0');
    std::memcpy(out.data(), &h, sizeof h);
    return out + voxels;
}

bool IsLosslessTsdfBytes(std::string_view bytes) {
    return bytes.size() >= sizeof kMagic && std::memcmp(bytes.data(), kMagic, sizeof kMagic) == 0;
}

std::optional<TsdfVoxelList> DecodeTsdfVoxels(std::string_view bytes, std::string* error) {
    auto fail = [&](const std::string& what) {
        if (error != nullptr) *error = "TSDF bytes: " + what;
        return std::optional<TsdfVoxelList>();
    };
    Header h;
    if (bytes.size() < sizeof h) return fail(At(bytes.size(), "truncated header"));
    std::memcpy(&h, bytes.data(), sizeof h);
    const bool quantised = std::memcmp(h.magic, kMagicQuantised, sizeof kMagicQuantised) == 0;
    if (!quantised && std::memcmp(h.magic, kMagic, sizeof kMagic) != 0) {
        return fail(At(0, "bad magic"));
    }
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
    if (std::string e = ReadVoxels(in, quantised, list); !e.empty()) return fail(e);
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
