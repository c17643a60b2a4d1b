// The KITTI .bin reader, the extension dispatch and the writers (PCD and PLY readers are in
// cloud_io_pcd.cpp and cloud_io_ply.cpp).
// The readers parse and bound-check headers themselves (PCL's PCDReader and PLYReader trust the
// header's counts, print their errors without file or line, and the PCD one can read out of
// bounds on a crafted file); PCL decodes LZF (cloud_io_pcd.cpp). The writers stay here: PCL's
// refuse an empty cloud and report failures on stderr or by exception, not as an error text.
#include <algorithm>
#include <cctype>
#include <charconv>
#include <cstdio>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "slam/io/cloud_io.h"
#include "slam/io/cloud_io_parse.h"

namespace certislam::slam {
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
