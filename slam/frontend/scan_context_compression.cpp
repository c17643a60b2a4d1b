// Compact Scan Context wire form: quantised uint16 heights in two byte planes, zstd.
#include "slam/frontend/scan_context_compression.h"

#include <zstd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string>

namespace certislam::slam {
namespace {

constexpr std::uint32_t kMagic = 0x315A4353;  // "SCZ1"
constexpr std::size_t kHeaderBytes = 16;      // magic, rings u16, sectors u16, range f32, step f32
constexpr std::uint16_t kMaxDimension = 4096;

}  // namespace

void ScanContextCompressionConfig::Validate() const {
    if (!(height_step_m > 0.0 && height_step_m <= 1.0)) {
        throw std::invalid_argument("ScanContextCompressionConfig.height_step_m = " +
                                    std::to_string(height_step_m) + ": must be in (0, 1]");
    }
    if (zstd_level < 1 || zstd_level > 19) {
        throw std::invalid_argument("ScanContextCompressionConfig.zstd_level = " +
                                    std::to_string(zstd_level) + ": must be in [1, 19]");
    }
}

std::vector<std::uint8_t> EncodeScanContextCompact(const ScanContext& descriptor,
                                                   const ScanContextCompressionConfig& config) {
    config.Validate();
    const auto rings = static_cast<std::uint16_t>(descriptor.bins.rows());
    const auto sectors = static_cast<std::uint16_t>(descriptor.bins.cols());
    const std::size_t n = std::size_t{rings} * sectors;
    std::vector<std::uint8_t> planes(2 * n);
    const float* bins = descriptor.bins.data();  // ring-major
    for (std::size_t i = 0; i < n; ++i) {
        const double steps = std::clamp(std::round(bins[i] / config.height_step_m), 0.0, 65535.0);
        const auto q = static_cast<std::uint16_t>(std::isfinite(steps) ? steps : 0.0);
        planes[i] = static_cast<std::uint8_t>(q & 0xFF);
        planes[n + i] = static_cast<std::uint8_t>(q >> 8);
    }
    const std::size_t bound = ZSTD_compressBound(planes.size());
    std::vector<std::uint8_t> bytes(kHeaderBytes + bound);
    const std::size_t written = ZSTD_compress(bytes.data() + kHeaderBytes, bound, planes.data(),
                                              planes.size(), config.zstd_level);
    if (ZSTD_isError(written)) {
        throw std::runtime_error(std::string("zstd compression failed: ") +
                                 ZSTD_getErrorName(written));
    }
    bytes.resize(kHeaderBytes + written);
    const auto range = static_cast<float>(descriptor.max_range_m);
    const auto step = static_cast<float>(config.height_step_m);
    std::memcpy(bytes.data(), &kMagic, 4);
    std::memcpy(bytes.data() + 4, &rings, 2);
    std::memcpy(bytes.data() + 6, &sectors, 2);
    std::memcpy(bytes.data() + 8, &range, 4);
    std::memcpy(bytes.data() + 12, &step, 4);
    return bytes;
}

std::optional<ScanContext> DecodeScanContextCompact(const std::vector<std::uint8_t>& bytes) {
    if (bytes.size() < kHeaderBytes) return std::nullopt;
    std::uint32_t magic = 0;
    std::uint16_t rings = 0, sectors = 0;
    float range = 0.0f, step = 0.0f;
    std::memcpy(&magic, bytes.data(), 4);
    std::memcpy(&rings, bytes.data() + 4, 2);
    std::memcpy(&sectors, bytes.data() + 6, 2);
    std::memcpy(&range, bytes.data() + 8, 4);
    std::memcpy(&step, bytes.data() + 12, 4);
    if (magic != kMagic || rings < 1 || sectors < 2 || rings > kMaxDimension ||
        sectors > kMaxDimension || !(range > 0.0f) || !std::isfinite(range) ||
        !(step > 0.0f && step <= 1.0f)) {
        return std::nullopt;
    }
    const std::size_t n = std::size_t{rings} * sectors;
    const std::uint8_t* frame = bytes.data() + kHeaderBytes;
    const std::size_t frame_size = bytes.size() - kHeaderBytes;
    if (ZSTD_getFrameContentSize(frame, frame_size) != 2ull * n) return std::nullopt;
    std::vector<std::uint8_t> planes(2 * n);
    const std::size_t got = ZSTD_decompress(planes.data(), planes.size(), frame, frame_size);
    if (ZSTD_isError(got) || got != planes.size()) return std::nullopt;
    ScanContext sc;
    sc.max_range_m = range;
    sc.bins.resize(rings, sectors);
    float* bins = sc.bins.data();
    for (std::size_t i = 0; i < n; ++i) {
        bins[i] = static_cast<float>(planes[i] | (planes[n + i] << 8)) * step;
    }
    sc.ring_key = sc.bins.rowwise().mean();  // as MakeScanContext computes the keys
    sc.sector_key = sc.bins.colwise().mean().transpose();
    return sc;
}

}  // namespace certislam::slam
