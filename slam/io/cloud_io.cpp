// KITTI .bin and PLY readers, the extension dispatch and the writers (PCD is in cloud_io_pcd.cpp).
// Written by hand rather than with PCL's readers: PCL's I/O would pull PCL into every user of
// these files, and its errors do not say which file or what was wrong.
#include <algorithm>
#include <cctype>
#include <charconv>
#include <cstdio>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "slam/io/cloud_io_internal.h"

namespace certislam::slam {
namespace cloud_io_internal {

std::optional<std::vector<unsigned char>> ReadFileBytes(const std::string& path, bool* too_big) {
    std::ifstream in(path, std::ios::binary | std::ios::ate);
    if (!in) return std::nullopt;
    const std::streamoff size = in.tellg();
    if (size < 0) return std::nullopt;
    if (static_cast<std::size_t>(size) > kMaxCloudFileBytes) {
        if (too_big != nullptr) *too_big = true;
        return std::nullopt;
    }
    std::vector<unsigned char> bytes(static_cast<std::size_t>(size));
    in.seekg(0);
    if (size > 0 && !in.read(reinterpret_cast<char*>(bytes.data()), size)) return std::nullopt;
    return bytes;
}

CloudReadResult ReadFailure(const std::string& path, bool too_big) {
    if (!too_big)
        return Fail(CloudReadResult::Status::kCannotOpen, path, 0, "cannot open or read the file");
    return Fail(CloudReadResult::Status::kUnsupported, path, 0,
                "file is over " + std::to_string(kMaxCloudFileBytes) +
                    " bytes, the largest cloud file read");
}

CloudReadResult Fail(CloudReadResult::Status status, const std::string& path, int line,
                     const std::string& message) {
    CloudReadResult result;
    result.status = status;
    result.error = path;
    if (line > 0) result.error.append(":").append(std::to_string(line));
    result.error.append(": ").append(message);
    return result;
}

std::vector<std::string_view> SplitWords(std::string_view line) {
    std::vector<std::string_view> words;
    std::size_t i = 0;
    while (i < line.size()) {
        while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r')) ++i;
        std::size_t j = i;
        while (j < line.size() && line[j] != ' ' && line[j] != '\t' && line[j] != '\r') ++j;
        if (j > i) words.push_back(line.substr(i, j - i));
        i = j;
    }
    return words;
}

std::optional<double> ParseDouble(std::string_view word) {
    double v = 0.0;
    const char* end = word.data() + word.size();
    const auto [ptr, ec] = std::from_chars(word.data(), end, v);
    if (ec != std::errc() || ptr != end) return std::nullopt;
    return v;
}

std::optional<long long> ParseCount(std::string_view word) {
    long long v = 0;
    const char* end = word.data() + word.size();
    const auto [ptr, ec] = std::from_chars(word.data(), end, v);
    if (ec != std::errc() || ptr != end || v < 0) return std::nullopt;
    return v;
}

LineView NextLine(const std::vector<unsigned char>& bytes, std::size_t offset) {
    const auto* begin = bytes.data() + offset;
    const auto* end = bytes.data() + bytes.size();
    const auto* nl = std::find(begin, end, static_cast<unsigned char>('\n'));
    const std::string_view text(reinterpret_cast<const char*>(begin),
                                static_cast<std::size_t>(nl - begin));
    return {text, static_cast<std::size_t>(nl - bytes.data()) + (nl == end ? 0 : 1)};
}

}  // namespace cloud_io_internal

namespace {

using namespace cloud_io_internal;
using Status = CloudReadResult::Status;

std::string Lowercase(std::string s) {
    std::transform(s.begin(), s.end(), s.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return s;
}

std::string ExtensionOf(const std::string& path) {
    const std::size_t dot = path.find_last_of('.');
    const std::size_t slash = path.find_last_of('/');
    if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
    return Lowercase(path.substr(dot));
}

// Opens `path` for writing and writes `header` then `data`; returns an error text or "".
std::string WriteFile(const std::string& path, const std::string& header, const void* data,
                      std::size_t size) {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    if (!out) return path + ": cannot open for writing";
    out.write(header.data(), static_cast<std::streamsize>(header.size()));
    if (size > 0) out.write(static_cast<const char*>(data), static_cast<std::streamsize>(size));
    out.flush();
    return out ? "" : path + ": write failed";
}

}  // namespace

CloudReadResult ReadKittiBin(const std::string& path) {
    bool too_big = false;
    const auto bytes = ReadFileBytes(path, &too_big);
    if (!bytes) return ReadFailure(path, too_big);
    constexpr std::size_t kRecord = 16;  // float32 x y z reflectance
    if (bytes->size() % kRecord != 0) {
        return Fail(Status::kTruncated, path, 0,
                    "size " + std::to_string(bytes->size()) +
                        " bytes is not a multiple of 16 (float32 x y z reflectance): truncated?");
    }
    CloudReadResult result;
    const std::size_t n = bytes->size() / kRecord;
    result.cloud.reserve(n);
    for (std::size_t i = 0; i < n; ++i) {
        float xyz[3];
        std::memcpy(xyz, bytes->data() + i * kRecord, sizeof(xyz));
        AddPoint(result, xyz[0], xyz[1], xyz[2]);
    }
    return result;
}

CloudReadResult ReadCloud(const std::string& path) {
    const std::string ext = ExtensionOf(path);
    if (ext == ".bin") return ReadKittiBin(path);
    if (ext == ".pcd") return ReadPcd(path);
    if (ext == ".ply") return ReadPly(path);
    return Fail(Status::kUnsupported, path, 0,
                "unknown extension '" + ext + "' (expected .pcd, .ply or .bin)");
}

std::string WritePcdBinary(const std::string& path, const PointCloud& cloud) {
    const std::string n = std::to_string(cloud.size());
    const std::string header =
        "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\n"
        "TYPE F F F\nCOUNT 1 1 1\nWIDTH " +
        n + "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " + n + "\nDATA binary\n";
    static_assert(sizeof(Eigen::Vector3f) == 12, "PointCloud must be packed float xyz");
    return WriteFile(path, header, cloud.data(), cloud.size() * 12);
}

std::string WritePlyBinary(const std::string& path, const PointCloud& cloud) {
    const std::string header =
        "ply\nformat binary_little_endian 1.0\nelement vertex " + std::to_string(cloud.size()) +
        "\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
    return WriteFile(path, header, cloud.data(), cloud.size() * 12);
}

std::string WriteKittiBin(const std::string& path, const PointCloud& cloud) {
    std::vector<float> data;
    data.reserve(cloud.size() * 4);
    for (const auto& p : cloud) data.insert(data.end(), {p.x(), p.y(), p.z(), 0.0f});
    return WriteFile(path, "", data.data(), data.size() * sizeof(float));
}

}  // namespace certislam::slam
