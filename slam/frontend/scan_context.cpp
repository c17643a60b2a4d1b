// Scan Context: descriptor, keys, column-shift distances and the wire form (Kim & Kim 2018).
#include "slam/frontend/scan_context.h"

#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>

#include "slam/core/check.h"

namespace certislam::slam {
namespace {

constexpr std::uint32_t kMagic = 0x31584353;  // "SCX1" little-endian
constexpr std::size_t kHeaderBytes = 16;      // magic, N_r, N_s, max range

[[noreturn]] void Invalid(const std::string& field, double value, const std::string& rule) {
    throw std::invalid_argument("ScanContextConfig." + field + " = " + std::to_string(value) +
                                ": must be " + rule);
}

// Azimuth in [0, 2pi) of (x, y) != 0: atan2 by a minimax polynomial, error below 3e-6 rad
// (a sector is 0.1 rad wide); cheaper than std::atan2, which dominated building a descriptor.
inline float Azimuth(float y, float x) {
    constexpr float kPi = std::numbers::pi_v<float>;
    const float ax = std::abs(x), ay = std::abs(y);
    const float a = std::min(ax, ay) / std::max(ax, ay);
    const float s = a * a;
    float r =
        a * (0.99997726f +
             s * (-0.33262347f +
                  s * (0.19354346f + s * (-0.11643287f + s * (0.05265332f - s * 0.0117212f)))));
    if (ay > ax) r = 0.5f * kPi - r;
    if (x < 0.0f) r = kPi - r;
    if (y < 0.0f) r = 2.0f * kPi - r;
    return r;
}

void ComputeKeys(ScanContext& sc) {
    sc.ring_key = sc.bins.rowwise().mean();
    sc.sector_key = sc.bins.colwise().mean().transpose();
}

int Wrap(int shift, int n) { return ((shift % n) + n) % n; }

// Yaw of a shift, wrapped to (-pi, pi].
double ShiftToYaw(int shift, int num_sectors) {
    const int s = Wrap(shift, num_sectors);
    const double yaw = 2.0 * std::numbers::pi * s / num_sectors;
    return yaw > std::numbers::pi ? yaw - 2.0 * std::numbers::pi : yaw;
}

// Coarse alignment: the shift minimising the squared difference of the sector keys.
int SectorKeyShift(const ScanContext& query, const ScanContext& candidate) {
    const int n = static_cast<int>(query.sector_key.size());
    int best = 0;
    double best_cost = std::numeric_limits<double>::infinity();
    for (int s = 0; s < n; ++s) {
        double cost = 0.0;
        for (int j = 0; j < n; ++j) {
            const double d = query.sector_key[j] - candidate.sector_key[(j + s) % n];
            cost += d * d;
        }
        if (cost < best_cost) {
            best_cost = cost;
            best = s;
        }
    }
    return best;
}

// Eq. (5): mean cosine distance over the column pairs that are both non-empty.
double DistanceAtShift(const ScanContextColumns& q, const ScanContextColumns& c, int shift) {
    const int n = static_cast<int>(q.columns.cols());
    double sum = 0.0;
    int pairs = 0;
    for (int j = 0; j < n; ++j) {
        const int k = Wrap(j + shift, n);
        if (q.non_empty[static_cast<std::size_t>(j)] == 0 ||
            c.non_empty[static_cast<std::size_t>(k)] == 0) {
            continue;
        }
        sum += 1.0 - static_cast<double>(q.columns.col(j).dot(c.columns.col(k)));
        ++pairs;
    }
    return pairs == 0 ? 1.0 : sum / pairs;
}

void CheckCompatible(const ScanContext& a, const ScanContext& b) {
    CERTISLAM_CHECK(a.bins.rows() == b.bins.rows() && a.bins.cols() == b.bins.cols());
    CERTISLAM_CHECK(a.bins.cols() >= 1);
}

}  // namespace

void ScanContextConfig::Validate() const {
    if (num_rings < 1) Invalid("num_rings", num_rings, ">= 1");
    if (num_sectors < 2) Invalid("num_sectors", num_sectors, ">= 2");
    if (!(max_range_m > 0.0)) Invalid("max_range_m", max_range_m, "> 0");
    if (!std::isfinite(sensor_height_m)) Invalid("sensor_height_m", sensor_height_m, "finite");
    if (!(fast_search_ratio > 0.0 && fast_search_ratio <= 0.5)) {
        Invalid("fast_search_ratio", fast_search_ratio, "in (0, 0.5]");
    }
}

ScanContext MakeScanContext(const PointCloud& cloud, const ScanContextConfig& config) {
    config.Validate();
    ScanContext sc;
    sc.max_range_m = config.max_range_m;
    sc.bins = ScanContextMatrix::Zero(config.num_rings, config.num_sectors);
    const float max_range = static_cast<float>(config.max_range_m);
    const float rings_per_m = static_cast<float>(config.num_rings / config.max_range_m);
    const float sectors_per_rad = static_cast<float>(config.num_sectors / (2.0 * std::numbers::pi));
    const float height = static_cast<float>(config.sensor_height_m);
    for (const Eigen::Vector3f& p : cloud) {
        const float range = std::sqrt(p.x() * p.x() + p.y() * p.y());
        if (!(range < max_range) || range <= 0.0f) continue;  // also skips NaN
        const float azimuth = Azimuth(p.y(), p.x());
        const int ring = std::min(static_cast<int>(range * rings_per_m), config.num_rings - 1);
        const int sector =
            std::min(static_cast<int>(azimuth * sectors_per_rad), config.num_sectors - 1);
        float& bin = sc.bins(ring, sector);
        bin = std::max(bin, p.z() + height);  // Eq. (2): max height; below -height stays 0
    }
    ComputeKeys(sc);
    return sc;
}

double ScanContextDistanceAtShift(const ScanContext& query, const ScanContext& candidate,
                                  int shift) {
    CheckCompatible(query, candidate);
    return DistanceAtShift(ScanContextColumns(query), ScanContextColumns(candidate), shift);
}

ScanContextColumns::ScanContextColumns(const ScanContext& sc)
    : columns(sc.bins), non_empty(static_cast<std::size_t>(sc.bins.cols()), 0) {
    for (Eigen::Index j = 0; j < columns.cols(); ++j) {
        const float norm = columns.col(j).norm();
        if (norm > 0.0f) {
            columns.col(j) /= norm;
            non_empty[static_cast<std::size_t>(j)] = 1;
        }
    }
}

ScanContextMatch ScanContextDistance(const ScanContext& query, const ScanContext& candidate) {
    CheckCompatible(query, candidate);
    return ScanContextDistance(ScanContextColumns(query), ScanContextColumns(candidate));
}

ScanContextMatch ScanContextDistance(const ScanContextColumns& q, const ScanContextColumns& c) {
    CERTISLAM_CHECK(q.columns.rows() == c.columns.rows() && q.columns.cols() == c.columns.cols());
    CERTISLAM_CHECK(q.columns.cols() >= 1);
    const int n = static_cast<int>(q.columns.cols());
    // All column cosines at once: cosines(j, k) = q_j . c_k for unit columns.
    const Eigen::MatrixXf cosines = q.columns.transpose() * c.columns;
    ScanContextMatch best;
    best.distance = std::numeric_limits<double>::infinity();
    for (int s = 0; s < n; ++s) {  // Eq. (6): minimum over all column shifts
        double sum = 0.0;
        int pairs = 0;
        for (int j = 0, k = s; j < n; ++j, k = k + 1 == n ? 0 : k + 1) {  // k = (j + s) mod n
            if (q.non_empty[static_cast<std::size_t>(j)] == 0 ||
                c.non_empty[static_cast<std::size_t>(k)] == 0) {
                continue;
            }
            sum += 1.0 - cosines(j, k);
            ++pairs;
        }
        const double d = pairs == 0 ? 1.0 : sum / pairs;
        if (d < best.distance) best = {d, s, 0.0};
    }
    best.yaw_rad = ShiftToYaw(best.shift, n);
    return best;
}

ScanContextMatch ScanContextDistanceFast(const ScanContext& query, const ScanContext& candidate,
                                         int search_radius) {
    CheckCompatible(query, candidate);
    CERTISLAM_CHECK(search_radius >= 0);
    const ScanContextColumns q(query), c(candidate);
    const int n = static_cast<int>(query.bins.cols());
    const int coarse = SectorKeyShift(query, candidate);
    ScanContextMatch best;
    best.distance = std::numeric_limits<double>::infinity();
    const int radius = std::min(search_radius, (n - 1) / 2);
    for (int k = -radius; k <= radius; ++k) {
        const int s = Wrap(coarse + k, n);
        const double d = DistanceAtShift(q, c, s);
        if (d < best.distance) best = {d, s, 0.0};
    }
    best.yaw_rad = ShiftToYaw(best.shift, n);
    return best;
}

ScanContextMatch ScanContextDistanceFast(const ScanContext& query, const ScanContext& candidate,
                                         const ScanContextConfig& config) {
    const int radius =
        std::max(1, static_cast<int>(std::lround(config.fast_search_ratio * config.num_sectors)));
    return ScanContextDistanceFast(query, candidate, radius);
}

std::vector<std::uint8_t> SerializeScanContext(const ScanContext& descriptor) {
    const auto rings = static_cast<std::uint32_t>(descriptor.bins.rows());
    const auto sectors = static_cast<std::uint32_t>(descriptor.bins.cols());
    const float range = static_cast<float>(descriptor.max_range_m);
    const std::size_t bins = std::size_t{rings} * sectors;
    std::vector<std::uint8_t> bytes(kHeaderBytes + 4 * (bins + rings));
    std::memcpy(bytes.data(), &kMagic, 4);
    std::memcpy(bytes.data() + 4, &rings, 4);
    std::memcpy(bytes.data() + 8, &sectors, 4);
    std::memcpy(bytes.data() + 12, &range, 4);
    std::memcpy(bytes.data() + kHeaderBytes, descriptor.bins.data(), 4 * bins);
    std::memcpy(bytes.data() + kHeaderBytes + 4 * bins, descriptor.ring_key.data(), 4 * rings);
    return bytes;
}

std::optional<ScanContext> DeserializeScanContext(const std::vector<std::uint8_t>& bytes) {
    if (bytes.size() < kHeaderBytes) return std::nullopt;
    std::uint32_t magic = 0, rings = 0, sectors = 0;
    float range = 0.0f;
    std::memcpy(&magic, bytes.data(), 4);
    std::memcpy(&rings, bytes.data() + 4, 4);
    std::memcpy(&sectors, bytes.data() + 8, 4);
    std::memcpy(&range, bytes.data() + 12, 4);
    if (magic != kMagic || rings < 1 || sectors < 2 || rings > 4096 || sectors > 4096 ||
        !(range > 0.0f)) {
        return std::nullopt;
    }
    const std::size_t bins = std::size_t{rings} * sectors;
    if (bytes.size() != kHeaderBytes + 4 * (bins + rings)) return std::nullopt;
    ScanContext sc;
    sc.max_range_m = range;
    sc.bins.resize(rings, sectors);
    std::memcpy(sc.bins.data(), bytes.data() + kHeaderBytes, 4 * bins);
    if (!sc.bins.allFinite()) return std::nullopt;
    ComputeKeys(sc);
    return sc;
}

}  // namespace certislam::slam
