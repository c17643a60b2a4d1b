// TsdfVolume: settings, integration (bounded rays through the truncation band) and queries;
// meshing, fusion, slab-wise fusion and bytes are in tsdf_mesh, tsdf_fuse, tsdf_slabs and
// tsdf_serialize.
#include "slam/mapping/tsdf.h"

#include <zstd.h>
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <utility>

#include "slam/core/check.h"
#include "slam/mapping/tsdf_fuse.h"
#include "slam/mapping/tsdf_impl.h"
#include "slam/mapping/tsdf_mesh.h"
#include "slam/mapping/tsdf_serialize.h"

namespace certislam::slam {
namespace {

using Leaf = openvdb::FloatGrid::TreeType::LeafNodeType;

void Require(bool ok, const char* field, double value, const char* rule) {
    if (!ok) {
        throw std::invalid_argument(std::string("TsdfConfig.") + field + " = " +
                                    std::to_string(value) + ": must be " + rule);
    }
}

// One ray to cast: its end point in the volume frame and the weight it carries.
struct Ray {
    Eigen::Vector3f end;
    float weight;
};

// Groups the points ending in one voxel into one ray to their mean, weighted by their count
// (voxblox's "merged" idea). Open addressing keyed by the voxel index relative to the sensor's
// voxel: points are within max_range_m, so 21 bits per axis never wrap.
std::vector<Ray> GroupByVoxel(const std::vector<Eigen::Vector3f>& ends,
                              const Eigen::Vector3f& origin, float inv_voxel) {
    const std::size_t capacity = std::bit_ceil(std::max<std::size_t>(16, 2 * ends.size()));
    const int shift = 64 - std::countr_zero(capacity);
    constexpr std::uint64_t kEmpty = ~std::uint64_t{0};
    std::vector<std::uint64_t> keys(capacity, kEmpty);
    std::vector<std::uint32_t> slot_ray(capacity);
    std::vector<Ray> rays;
    rays.reserve(ends.size());
    const Eigen::Vector3f base = (origin * inv_voxel).array().floor();
    for (const auto& p : ends) {
        const Eigen::Vector3f q = (p * inv_voxel).array().floor() - base.array();
        const auto pack = [](float v) {
            return std::uint64_t(std::int64_t(v) + (1 << 20)) & 0x1FFFFF;
        };
        const std::uint64_t key = pack(q.x()) << 42 | pack(q.y()) << 21 | pack(q.z());
        std::size_t s = (key * 0x9E3779B97F4A7C15ULL) >> shift;
        while (keys[s] != kEmpty && keys[s] != key) s = (s + 1) & (capacity - 1);
        if (keys[s] == kEmpty) {
            keys[s] = key;
            slot_ray[s] = static_cast<std::uint32_t>(rays.size());
            rays.push_back({p, 1.0f});
        } else {
            Ray& r = rays[slot_ray[s]];
            r.end += p;  // a running sum; divided by the count below
            r.weight += 1.0f;
        }
    }
    for (Ray& r : rays) {
        r.end /= r.weight;
        r.weight = 1.0f;
    }
    return rays;
}

// Updates voxels through cached leaf pointers: consecutive voxels of a ray mostly share an
// 8^3 leaf, so the tree is walked only when the ray enters a new leaf.
class BandUpdater {
  public:
    explicit BandUpdater(TsdfVolume::Impl& impl)
        : impl_(impl), sdf_acc_(impl.sdf->tree()), w_acc_(impl.weight->tree()) {
        recent_.fill(openvdb::Coord::max());
    }

    void Update(const openvdb::Coord& ijk, float tsdf, float w) {
        const openvdb::Coord origin = ijk & ~openvdb::Coord::ValueType(Leaf::DIM - 1);
        if (sdf_leaf_ == nullptr || origin != origin_) {
            sdf_leaf_ = sdf_acc_.touchLeaf(ijk);
            w_leaf_ = w_acc_.touchLeaf(ijk);
            origin_ = origin;
            NoteTouched(origin);
        }
        const openvdb::Index i = Leaf::coordToOffset(ijk);
        const float old_w = w_leaf_->getValue(i);
        const float new_w = old_w + w;
        sdf_leaf_->setValueOn(i, (sdf_leaf_->getValue(i) * old_w + tsdf * w) / new_w);
        w_leaf_->setValueOn(i, std::min(new_w, impl_.config.max_weight));
        ++updates_;
    }

    std::size_t Finish() {
        impl_.dirty_blocks.insert(touched_.begin(), touched_.end());
        return updates_;
    }

  private:
    // A small direct-mapped filter keeps the touched list near the number of distinct leaves.
    void NoteTouched(const openvdb::Coord& origin) {
        const std::size_t h = origin.hash<12>();
        if (recent_[h] == origin) return;
        recent_[h] = origin;
        touched_.push_back(origin);
    }

    TsdfVolume::Impl& impl_;
    openvdb::FloatGrid::Accessor sdf_acc_, w_acc_;
    Leaf* sdf_leaf_ = nullptr;
    Leaf* w_leaf_ = nullptr;
    openvdb::Coord origin_;
    std::array<openvdb::Coord, 4096> recent_;
    std::vector<openvdb::Coord> touched_;
    std::size_t updates_ = 0;
};

// The band one ray updates, in metres and (squared) voxel-centre distance from the ray.
struct Band {
    float voxel;      // voxel edge
    float front;      // truncation in front of the hit (positive side)
    float behind;     // extent behind the hit (negative side), <= front
    float radius_sq;  // squared footprint radius: centres farther from the ray are skipped
    bool dropoff;     // behind the hit, the weight falls linearly to 0 at -behind
};

// Amanatides-Woo traversal of the voxels the ray crosses between depth - front and
// depth + behind. A crossed voxel is updated only when its centre c lies within the footprint
// radius of the ray: the projective distance depth - (c - o).dir is the distance to the plane
// through the hit perpendicular to the ray, which differs from the distance to the surface by
// up to (offset of c from the ray) / tan(incidence); at grazing incidence an off-ray centre
// next to the surface gets the wrong sign. Keeping centres within half a voxel of the ray
// bounds that error by half a voxel (the accuracy the mesh promises).
void CastRay(const Eigen::Vector3f& o, const Ray& ray, const Band& band, BandUpdater* up) {
    const float voxel = band.voxel;
    const Eigen::Vector3f d = ray.end - o;
    const float depth = d.norm();
    const Eigen::Vector3f dir = d / depth;
    const float t0 = std::max(depth - band.front, 0.0f), t1 = depth + band.behind;
    const Eigen::Vector3f q0 = (o + t0 * dir) / voxel + Eigen::Vector3f::Constant(0.5f);
    std::array<int, 3> ijk, step;
    std::array<float, 3> t_max, t_delta;
    for (int a = 0; a < 3; ++a) {
        ijk[a] = static_cast<int>(std::floor(q0[a]));
        step[a] = dir[a] > 0 ? 1 : -1;
        if (dir[a] == 0.0f) {
            t_max[a] = t_delta[a] = std::numeric_limits<float>::infinity();
            continue;
        }
        const float boundary = static_cast<float>(ijk[a] + (dir[a] > 0 ? 1 : 0));
        t_max[a] = t0 + (boundary - q0[a]) * voxel / dir[a];
        t_delta[a] = voxel / std::abs(dir[a]);
    }
    while (true) {
        const Eigen::Vector3f oc =
            Eigen::Vector3f(ijk[0] * voxel, ijk[1] * voxel, ijk[2] * voxel) - o;
        const float t = oc.dot(dir);
        const float sdf = depth - t;
        if (sdf >= -band.behind && oc.squaredNorm() - t * t <= band.radius_sq) {
            float w = ray.weight;
            // Curless & Levoy 1996: behind the surface the space is presumed, not observed.
            if (band.dropoff && sdf < 0.0f) w *= (band.behind + sdf) / band.behind;
            if (w > 0.0f) up->Update({ijk[0], ijk[1], ijk[2]}, std::min(sdf, band.front), w);
        }
        const int a =
            t_max[0] < t_max[1] ? (t_max[0] < t_max[2] ? 0 : 2) : (t_max[1] < t_max[2] ? 1 : 2);
        if (t_max[a] > t1) break;
        ijk[a] += step[a];
        t_max[a] += t_delta[a];
    }
}

// The sizes of a live volume's grids.
TsdfStats GridStats(const TsdfVolume::Impl& im) {
    TsdfStats s;
    s.active_voxels = im.weight->tree().activeVoxelCount();
    s.leaf_blocks = im.weight->tree().leafCount();
    s.allocated_voxels = s.leaf_blocks * Leaf::SIZE;
    s.memory_bytes = im.sdf->tree().memUsage() + im.weight->tree().memUsage();
    return s;
}

// zstd over SerializeTsdf's voxels (masks and byte-planed floats compress about twofold; the
// mapper's wire payload does the same).
constexpr int kPackZstdLevel = 3;

std::string ZstdPack(const std::string& bytes) {
    std::string out(ZSTD_compressBound(bytes.size()), '\0');
    const std::size_t n =
        ZSTD_compress(out.data(), out.size(), bytes.data(), bytes.size(), kPackZstdLevel);
    CERTISLAM_CHECK(!ZSTD_isError(n));
    out.resize(n);
    out.shrink_to_fit();
    return out;
}

// The bytes ZstdPack was given (our own frame: its size is recorded in it).
std::string ZstdUnpack(const std::string& frame) {
    const unsigned long long size = ZSTD_getFrameContentSize(frame.data(), frame.size());
    CERTISLAM_CHECK(size != ZSTD_CONTENTSIZE_ERROR && size != ZSTD_CONTENTSIZE_UNKNOWN);
    std::string out(size, '\0');
    const std::size_t n = ZSTD_decompress(out.data(), out.size(), frame.data(), frame.size());
    CERTISLAM_CHECK(!ZSTD_isError(n) && n == size);
    return out;
}

// Frees the grids and the mesh cache of a live `im`, keeping `bytes` (its SerializeTsdf).
void PackTsdf(TsdfVolume::Impl& im, const std::string& bytes) {
    im.packed_stats = GridStats(im);
    im.packed = ZstdPack(bytes);
    im.packed_stats.memory_bytes = im.packed.size();
    im.sdf.reset();
    im.weight.reset();
    std::unordered_set<openvdb::Coord>().swap(im.dirty_blocks);
    std::unordered_map<openvdb::Coord, TsdfBlockMesh>().swap(im.mesh_cache);
}

// A live copy of a packed `im` (every block dirty). Its bytes were checked when they were kept.
std::unique_ptr<TsdfVolume::Impl> UnpackTsdf(const TsdfVolume::Impl& im) {
    std::string error;
    auto live = DeserializeTsdf(ZstdUnpack(im.packed), &error);
    CERTISLAM_CHECK(live != nullptr);
    return live;
}

// The state to read: `im` itself when live, else a decoded copy kept in `*decoded`.
const TsdfVolume::Impl& Readable(const TsdfVolume::Impl& im,
                                 std::unique_ptr<TsdfVolume::Impl>* decoded) {
    if (!im.IsPacked()) return im;
    *decoded = UnpackTsdf(im);
    return **decoded;
}

}  // namespace

// Its bytes were checked when they were kept.
TsdfVoxelList UnpackVoxels(const TsdfVolume::Impl& im) {
    std::string error;
    std::optional<TsdfVoxelList> list = DecodeTsdfVoxels(ZstdUnpack(im.packed), &error);
    CERTISLAM_CHECK(list.has_value());
    return std::move(*list);
}

void TsdfConfig::Validate() const {
    Require(voxel_size_m >= 0.01 && voxel_size_m <= 5.0, "voxel_size_m", voxel_size_m,
            "in [0.01, 5]");
    Require(truncation_voxels >= 1.0 && truncation_voxels <= 20.0, "truncation_voxels",
            truncation_voxels, "in [1, 20]");
    Require(behind_surface_voxels >= 0.5 && behind_surface_voxels <= truncation_voxels,
            "behind_surface_voxels", behind_surface_voxels, "in [0.5, truncation_voxels]");
    Require(ray_radius_voxels >= 0.1 && ray_radius_voxels <= 0.87, "ray_radius_voxels",
            ray_radius_voxels, "in [0.1, 0.87] (0.87: every voxel the ray crosses)");
    Require(min_range_m >= 0.0, "min_range_m", min_range_m, ">= 0");
    Require(max_range_m > min_range_m && max_range_m <= 1000.0, "max_range_m", max_range_m,
            "> min_range_m and <= 1000");
    Require(max_weight > 0.0f, "max_weight", max_weight, "> 0");
    Require(min_mesh_weight >= 0.0f, "min_mesh_weight", min_mesh_weight, ">= 0");
}

TsdfVolume::Impl::Impl(const TsdfConfig& cfg) : config(cfg) {
    static std::once_flag once;
    std::call_once(once, [] { openvdb::initialize(); });
    sdf = openvdb::FloatGrid::create(static_cast<float>(cfg.truncation_m()));
    weight = openvdb::FloatGrid::create(0.0f);
    const auto transform = openvdb::math::Transform::createLinearTransform(cfg.voxel_size_m);
    sdf->setTransform(transform);
    weight->setTransform(transform->copy());
    sdf->setName("sdf");
    weight->setName("weight");
}

void TsdfVolume::Impl::MarkAllDirty() {
    for (auto it = weight->tree().cbeginLeaf(); it; ++it) dirty_blocks.insert(it->origin());
}

TsdfVolume::TsdfVolume(const TsdfConfig& config) {
    config.Validate();
    impl_ = std::make_unique<Impl>(config);
}

TsdfVolume::TsdfVolume(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
TsdfVolume::~TsdfVolume() = default;
TsdfVolume::TsdfVolume(TsdfVolume&&) noexcept = default;
TsdfVolume& TsdfVolume::operator=(TsdfVolume&&) noexcept = default;

TsdfVolume::Impl& TsdfVolume::Writable() {
    if (impl_->IsPacked()) impl_ = UnpackTsdf(*impl_);
    return *impl_;
}

void TsdfVolume::Pack() {
    if (!impl_->IsPacked()) PackTsdf(*impl_, SerializeTsdf(*impl_));
}

bool TsdfVolume::packed() const { return impl_->IsPacked(); }

std::optional<TsdfVolume> TsdfVolume::DeserializePacked(std::string_view bytes,
                                                        std::string* error) {
    // Checked as a voxel list: the grids are never built (their sizes follow from the list).
    const std::optional<TsdfVoxelList> list = DecodeTsdfVoxels(bytes, error);
    if (!list) return std::nullopt;
    auto impl = std::make_unique<Impl>(list->config);
    PackTsdf(*impl, std::string(bytes));
    impl->packed_stats.active_voxels = list->sdf.size();
    impl->packed_stats.leaf_blocks = list->origins.size();
    impl->packed_stats.allocated_voxels = list->origins.size() * Leaf::SIZE;
    return TsdfVolume(std::move(impl));
}

TsdfVolume TsdfVolume::Clone() const {
    auto impl = std::make_unique<Impl>(impl_->config);
    if (impl_->IsPacked()) {
        impl->sdf.reset();
        impl->weight.reset();
        impl->packed = impl_->packed;
        impl->packed_stats = impl_->packed_stats;
        return TsdfVolume(std::move(impl));
    }
    impl->sdf = impl_->sdf->deepCopy();
    impl->weight = impl_->weight->deepCopy();
    impl->dirty_blocks = impl_->dirty_blocks;
    impl->mesh_cache = impl_->mesh_cache;
    return TsdfVolume(std::move(impl));
}

TsdfIntegrateResult TsdfVolume::Integrate(const PointCloud& points,
                                          const Eigen::Isometry3d& T_volume_sensor) {
    Impl& im = Writable();
    const TsdfConfig& cfg = im.config;
    const Eigen::Matrix3f R = T_volume_sensor.rotation().cast<float>();
    const Eigen::Vector3f origin = T_volume_sensor.translation().cast<float>();
    const float min_sq = static_cast<float>(cfg.min_range_m * cfg.min_range_m);
    const float max_sq = static_cast<float>(cfg.max_range_m * cfg.max_range_m);
    std::vector<Eigen::Vector3f> ends;
    ends.reserve(points.size());
    for (const auto& p : points) {
        const float r2 = p.squaredNorm();
        if (r2 >= min_sq && r2 <= max_sq && std::isfinite(r2)) ends.emplace_back(R * p + origin);
    }
    TsdfIntegrateResult result;
    result.points_used = ends.size();
    if (ends.empty()) {
        result.status = TsdfIntegrateResult::Status::kNoValidRays;
        return result;
    }
    const float voxel = static_cast<float>(cfg.voxel_size_m);
    const float radius = static_cast<float>(cfg.ray_radius_voxels) * voxel;
    const Band band{voxel, static_cast<float>(cfg.truncation_m()),
                    static_cast<float>(cfg.behind_surface_voxels) * voxel, radius * radius,
                    cfg.weight_dropoff};
    BandUpdater updater(im);
    if (cfg.group_points_by_voxel) {
        const std::vector<Ray> rays = GroupByVoxel(ends, origin, 1.0f / voxel);
        for (const Ray& r : rays) CastRay(origin, r, band, &updater);
        result.rays_cast = rays.size();
    } else {
        for (const auto& p : ends) CastRay(origin, Ray{p, 1.0f}, band, &updater);
        result.rays_cast = ends.size();
    }
    result.voxel_updates = updater.Finish();
    return result;
}

std::optional<TsdfVoxel> TsdfVolume::Query(const Eigen::Vector3d& p_volume) const {
    std::unique_ptr<Impl> decoded;
    const Impl& im = Readable(*impl_, &decoded);
    const Eigen::Vector3d q = (p_volume / im.config.voxel_size_m).array().round();
    const openvdb::Coord ijk(int(q.x()), int(q.y()), int(q.z()));
    const float w = im.weight->tree().getValue(ijk);
    if (w <= 0.0f) return std::nullopt;
    return TsdfVoxel{im.sdf->tree().getValue(ijk), w};
}

TsdfStats TsdfVolume::Stats() const {
    return impl_->IsPacked() ? impl_->packed_stats : GridStats(*impl_);
}

const TsdfConfig& TsdfVolume::config() const { return impl_->config; }

std::size_t TsdfVolume::last_remeshed_blocks() const { return impl_->last_remeshed; }

void TsdfVolume::FuseVoxels(const TsdfVolume& other, const Eigen::Isometry3d& T_this_other) {
    std::unique_ptr<Impl> decoded;
    const Impl& src = Readable(*other.impl_, &decoded);
    FuseTsdfVoxels(Writable(), src, T_this_other);
}

TriangleMesh TsdfVolume::ExtractMesh() {
    if (!impl_->IsPacked()) return ExtractTsdfMesh(*impl_);
    const std::unique_ptr<Impl> decoded = UnpackTsdf(*impl_);
    TriangleMesh mesh = ExtractTsdfMesh(*decoded);
    impl_->last_remeshed = decoded->last_remeshed;
    return mesh;
}

bool TsdfVolume::SameVoxels(const TsdfVolume& other) const {
    std::unique_ptr<Impl> a, b;
    return SameTsdfVoxels(Readable(*impl_, &a), Readable(*other.impl_, &b));
}

std::string TsdfVolume::Serialize(int sdf_bits) const {
    if (!impl_->IsPacked()) return SerializeTsdf(*impl_, sdf_bits);
    std::string bytes = ZstdUnpack(impl_->packed);
    if (sdf_bits == 32 && IsLosslessTsdfBytes(bytes)) return bytes;
    std::unique_ptr<Impl> decoded;
    return SerializeTsdf(Readable(*impl_, &decoded), sdf_bits);
}

std::optional<TsdfVolume> TsdfVolume::Deserialize(std::string_view bytes, std::string* error) {
    auto impl = DeserializeTsdf(bytes, error);
    if (!impl) return std::nullopt;
    return TsdfVolume(std::move(impl));
}

}  // namespace certislam::slam
