// Cloud compression: quantise, Morton-sort, delta per axis (mod 2^16), byte planes, zstd.
#include "slam/io/cloud_compression.h"

#include <zstd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <numeric>
#include <stdexcept>

namespace certislam::slam {
namespace {

constexpr std::uint32_t kMagic = 0x315A4343;    // "CCZ1"
constexpr std::size_t kHeaderBytes = 16;        // magic, count, resolution (float64)
constexpr std::uint32_t kMaxPoints = 1u << 24;  // refuse to allocate more for untrusted input
constexpr double kMaxSteps = 32767.0;

// Spreads the 16 bits of v to every third bit of a 48-bit word.
std::uint64_t Spread3(std::uint64_t v) {
    v &= 0xFFFF;
    v = (v | (v << 16)) & 0x0000FF0000FFull;
    v = (v | (v << 8)) & 0x00F00F00F00Full;
    v = (v | (v << 4)) & 0x0C30C30C30C3ull;
    v = (v | (v << 2)) & 0x249249249249ull;
    return v;
}

using Quantised = std::array<std::uint16_t, 3>;  // offset by 32768

std::uint64_t Morton(const Quantised& q) {
    return Spread3(q[0]) | (Spread3(q[1]) << 1) | (Spread3(q[2]) << 2);
}

CloudDecodeResult Malformed(std::string error) {
    CloudDecodeResult r;
    r.status = CloudDecodeResult::Status::kMalformed;
    r.error = std::move(error);
    return r;
}

}  // namespace

void CloudCompressionConfig::Validate() const {
    if (!(resolution_m > 0.0 && resolution_m <= 1.0)) {
        throw std::invalid_argument("CloudCompressionConfig.resolution_m = " +
                                    std::to_string(resolution_m) + ": must be in (0, 1]");
    }
    if (zstd_level < 1 || zstd_level > 19) {
        throw std::invalid_argument("CloudCompressionConfig.zstd_level = " +
                                    std::to_string(zstd_level) + ": must be in [1, 19]");
    }
}

CloudEncodeResult EncodeCloud(const PointCloud& cloud, const CloudCompressionConfig& config) {
    config.Validate();
    CloudEncodeResult result;
    std::vector<Quantised> points;
    points.reserve(cloud.size());
    for (const Eigen::Vector3f& p : cloud) {
        const Eigen::Vector3d s = p.cast<double>() / config.resolution_m;
        if (!s.allFinite() || s.cwiseAbs().maxCoeff() > kMaxSteps) {
            ++result.points_dropped;
            continue;
        }
        Quantised q;
        for (int k = 0; k < 3; ++k) q[k] = static_cast<std::uint16_t>(std::lround(s[k]) + 32768);
        points.push_back(q);
    }
    // Morton order puts neighbours next to each other: deltas stay small and compress well.
    std::vector<std::uint64_t> keys(points.size());
    for (size_t i = 0; i < points.size(); ++i) keys[i] = Morton(points[i]);
    std::vector<std::uint32_t> order(points.size());
    std::iota(order.begin(), order.end(), 0u);
    std::sort(order.begin(), order.end(), [&](auto a, auto b) { return keys[a] < keys[b]; });
    const std::size_t n = points.size();
    std::vector<std::uint8_t> planes(6 * n);
    Quantised previous = {32768, 32768, 32768};
    for (size_t i = 0; i < n; ++i) {
        const Quantised& q = points[order[i]];
        for (int k = 0; k < 3; ++k) {
            const auto delta = static_cast<std::uint16_t>(q[k] - previous[k]);  // mod 2^16
            planes[(2 * k) * n + i] = static_cast<std::uint8_t>(delta & 0xFF);
            planes[(2 * k + 1) * n + i] = static_cast<std::uint8_t>(delta >> 8);
        }
        previous = q;
    }
    const std::size_t bound = ZSTD_compressBound(planes.size());
    result.bytes.resize(kHeaderBytes + bound);
    const std::size_t written = ZSTD_compress(result.bytes.data() + kHeaderBytes, bound,
                                              planes.data(), planes.size(), config.zstd_level);
    if (ZSTD_isError(written)) {
        throw std::runtime_error(std::string("zstd compression failed: ") +
                                 ZSTD_getErrorName(written));
    }
    result.bytes.resize(kHeaderBytes + written);
    const auto count = static_cast<std::uint32_t>(n);
    std::memcpy(result.bytes.data(), &kMagic, 4);
    std::memcpy(result.bytes.data() + 4, &count, 4);
    std::memcpy(result.bytes.data() + 8, &config.resolution_m, 8);
    return result;
}

bool IsEncodedCloud(const std::uint8_t* data, std::size_t size) {
    std::uint32_t magic = 0;
    if (size < kHeaderBytes) return false;
    std::memcpy(&magic, data, 4);
    return magic == kMagic;
}

CloudDecodeResult DecodeCloud(const std::uint8_t* data, std::size_t size) {
    if (!IsEncodedCloud(data, size)) return Malformed("not an encoded cloud (magic or size)");
    std::uint32_t count = 0;
    double resolution = 0.0;
    std::memcpy(&count, data + 4, 4);
    std::memcpy(&resolution, data + 8, 8);
    if (count > kMaxPoints) return Malformed("point count " + std::to_string(count) + " too large");
    if (!(resolution > 0.0 && resolution <= 1.0)) return Malformed("resolution out of (0, 1]");
    const std::size_t n = count;
    const unsigned long long declared =
        ZSTD_getFrameContentSize(data + kHeaderBytes, size - kHeaderBytes);
    if (declared != 6ull * n) return Malformed("compressed size does not match the point count");
    std::vector<std::uint8_t> planes(6 * n);
    const std::size_t got =
        ZSTD_decompress(planes.data(), planes.size(), data + kHeaderBytes, size - kHeaderBytes);
    if (ZSTD_isError(got) || got != planes.size()) {
        return Malformed(std::string("bad compressed data: ") +
                         (ZSTD_isError(got) ? ZSTD_getErrorName(got) : "short"));
    }
    CloudDecodeResult result;
    result.resolution_m = resolution;
    result.cloud.resize(n);
    Quantised q = {32768, 32768, 32768};
    for (size_t i = 0; i < n; ++i) {
        for (int k = 0; k < 3; ++k) {
            const auto delta = static_cast<std::uint16_t>(planes[(2 * k) * n + i] |
                                                          (planes[(2 * k + 1) * n + i] << 8));
            q[k] = static_cast<std::uint16_t>(q[k] + delta);
            result.cloud[i][k] = static_cast<float>((static_cast<int>(q[k]) - 32768) * resolution);
        }
    }
    return result;
}

}  // namespace certislam::slam
