// Tests of the point-cloud readers on the real data files and on deliberately broken files.
#include "slam/io/cloud_io.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>
#include "tests/data_paths.h"

namespace certislam::slam {
namespace {

namespace fs = std::filesystem;
using Status = CloudReadResult::Status;

const std::string kLidar = test_data::DataPath("lidar/");

fs::path TempDir() {
    const fs::path dir =
        fs::temp_directory_path() / ("certislam_cloud_io_" + std::to_string(::getpid()));
    fs::create_directories(dir);
    return dir;
}

void WriteText(const fs::path& path, const std::string& text) {
    std::ofstream out(path, std::ios::binary);
    out << text;
}

std::vector<unsigned char> Bytes(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

TEST(CloudIo, ReadsKittiScanWithAllPoints) {
    const std::string path = kLidar + "kitti00_scancontext_samples/velodyne/000094.bin";
    const CloudReadResult r = ReadKittiBin(path);
    ASSERT_TRUE(r.ok()) << r.error;
    EXPECT_EQ(r.cloud.size() + r.dropped_non_finite, fs::file_size(path) / 16);
    EXPECT_GT(r.cloud.size(), 120000u);
    float max_range = 0.0f;
    for (const auto& p : r.cloud) max_range = std::max(max_range, p.head<2>().norm());
    EXPECT_GT(max_range, 50.0f);  // HDL-64E reaches ~80 m
    EXPECT_LT(max_range, 130.0f);
}

TEST(CloudIo, ReadsPaddedMulranPcdByDeclaredCount) {
    const CloudReadResult r = ReadPcd(kLidar + "mulran_kaist03_keyframes/Scans/000000.pcd");
    ASSERT_TRUE(r.ok()) << r.error;
    EXPECT_EQ(r.cloud.size() + r.dropped_non_finite, 37101u);  // POINTS in the header
}

TEST(CloudIo, ReadsHdlPairPcd) {
    const CloudReadResult r = ReadCloud(kLidar + "hdl_pair_fast_gicp/251370668.pcd");
    ASSERT_TRUE(r.ok()) << r.error;
    EXPECT_EQ(r.cloud.size() + r.dropped_non_finite, 69088u);
}

TEST(CloudIo, BinaryPlyAndPcdRoundTrip) {
    const CloudReadResult kitti =
        ReadCloud(kLidar + "kitti00_scancontext_samples/velodyne/000198.bin");
    ASSERT_TRUE(kitti.ok()) << kitti.error;
    const fs::path dir = TempDir();
    ASSERT_EQ(WritePlyBinary(dir / "a.ply", kitti.cloud), "");
    ASSERT_EQ(WritePcdBinary(dir / "a.pcd", kitti.cloud), "");
    ASSERT_EQ(WriteKittiBin(dir / "a.bin", kitti.cloud), "");
    for (const char* name : {"a.ply", "a.pcd", "a.bin"}) {
        const CloudReadResult r = ReadCloud(dir / name);
        ASSERT_TRUE(r.ok()) << r.error;
        EXPECT_EQ(r.cloud, kitti.cloud) << name;
    }
}

TEST(CloudIo, AsciiPcdWithExtraFieldsAndCounts) {
    const fs::path path = TempDir() / "ascii.pcd";
    WriteText(path,
              "# comment\nVERSION .7\nFIELDS rgb x normal y z\nSIZE 4 8 4 4 2\nTYPE U F F F I\n"
              "COUNT 1 1 3 1 1\nWIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA ascii\n"
              "7 1.5 0 0 1 -2.25 3\n8 nan 0 0 1 0 0\n");
    const CloudReadResult r = ReadPcd(path);
    ASSERT_TRUE(r.ok()) << r.error;
    ASSERT_EQ(r.cloud.size(), 1u);
    EXPECT_EQ(r.dropped_non_finite, 1);
    EXPECT_EQ(r.cloud[0], Eigen::Vector3f(1.5f, -2.25f, 3.0f));
}

TEST(CloudIo, BinaryPcdWithMixedTypes) {
    const fs::path path = TempDir() / "mixed.pcd";
    std::string text =
        "VERSION 0.7\nFIELDS x y z ring\nSIZE 8 2 4 1\nTYPE F I F U\nCOUNT 1 1 1 1\n"
        "WIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA binary\n";
    const double x = 4.5;
    const std::int16_t y = -7;
    const float z = 0.25f;
    const std::uint8_t ring = 3;
    text.append(reinterpret_cast<const char*>(&x), 8);
    text.append(reinterpret_cast<const char*>(&y), 2);
    text.append(reinterpret_cast<const char*>(&z), 4);
    text.append(reinterpret_cast<const char*>(&ring), 1);
    WriteText(path, text);
    const CloudReadResult r = ReadPcd(path);
    ASSERT_TRUE(r.ok()) << r.error;
    ASSERT_EQ(r.cloud.size(), 1u);
    EXPECT_EQ(r.cloud[0], Eigen::Vector3f(4.5f, -7.0f, 0.25f));
}

// A binary_compressed file made by hand: field-major data, one LZF literal run and one
// back reference (the two y values equal the two x values).
TEST(CloudIo, BinaryCompressedPcdDecodesLzf) {
    const fs::path path = TempDir() / "compressed.pcd";
    std::string text =
        "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\n"
        "POINTS 2\nDATA binary_compressed\n";
    const float xs[2] = {1.0f, 2.0f}, zs[2] = {5.0f, 6.0f};
    std::string lzf;
    lzf.push_back(7);  // literal: 8 bytes (the x values)
    lzf.append(reinterpret_cast<const char*>(xs), 8);
    lzf.push_back(static_cast<char>((6 << 5) | 0));  // back reference, length 6 + 2 = 8
    lzf.push_back(7);                                // distance 7 + 1 = 8 bytes back
    lzf.push_back(7);                                // literal: 8 bytes (the z values)
    lzf.append(reinterpret_cast<const char*>(zs), 8);
    const std::uint32_t sizes[2] = {static_cast<std::uint32_t>(lzf.size()), 24};
    text.append(reinterpret_cast<const char*>(sizes), 8);
    text += lzf;
    WriteText(path, text);
    const CloudReadResult r = ReadPcd(path);
    ASSERT_TRUE(r.ok()) << r.error;
    ASSERT_EQ(r.cloud.size(), 2u);
    EXPECT_EQ(r.cloud[0], Eigen::Vector3f(1.0f, 1.0f, 5.0f));
    EXPECT_EQ(r.cloud[1], Eigen::Vector3f(2.0f, 2.0f, 6.0f));
}

TEST(CloudIo, AsciiPlyWithFacesAfterVertices) {
    const fs::path path = TempDir() / "mesh.ply";
    WriteText(path,
              "ply\nformat ascii 1.0\ncomment made by hand\nelement vertex 3\nproperty float x\n"
              "property float y\nproperty float z\nproperty uchar red\nelement face 1\n"
              "property list uchar int vertex_indices\nend_header\n0 0 0 255\n1 0 0 255\n"
              "0 1 0.5 255\n3 0 1 2\n");
    const CloudReadResult r = ReadPly(path);
    ASSERT_TRUE(r.ok()) << r.error;
    ASSERT_EQ(r.cloud.size(), 3u);
    EXPECT_EQ(r.cloud[2], Eigen::Vector3f(0.0f, 1.0f, 0.5f));
}

TEST(CloudIo, TruncatedFilesNameFileAndFault) {
    const fs::path dir = TempDir();
    const auto kitti = Bytes(kLidar + "kitti00_scancontext_samples/velodyne/000094.bin");
    WriteText(dir / "cut.bin", std::string(kitti.begin(), kitti.begin() + 1000 * 16 + 5));
    const CloudReadResult bin = ReadCloud(dir / "cut.bin");
    EXPECT_EQ(bin.status, Status::kTruncated);
    EXPECT_NE(bin.error.find("cut.bin"), std::string::npos) << bin.error;
    EXPECT_NE(bin.error.find("multiple of 16"), std::string::npos) << bin.error;

    const auto pcd = Bytes(kLidar + "hdl_pair_fast_gicp/251370668.pcd");
    WriteText(dir / "cut.pcd", std::string(pcd.begin(), pcd.begin() + pcd.size() / 2));
    const CloudReadResult p = ReadCloud(dir / "cut.pcd");
    EXPECT_EQ(p.status, Status::kTruncated);
    EXPECT_NE(p.error.find("cut.pcd"), std::string::npos) << p.error;
    EXPECT_NE(p.error.find("POINTS 69088"), std::string::npos) << p.error;

    ASSERT_EQ(WritePlyBinary(dir / "full.ply", PointCloud(100, Eigen::Vector3f::Ones())), "");
    const auto ply = Bytes(dir / "full.ply");
    WriteText(dir / "cut.ply", std::string(ply.begin(), ply.end() - 7));
    const CloudReadResult y = ReadCloud(dir / "cut.ply");
    EXPECT_EQ(y.status, Status::kTruncated);
    EXPECT_NE(y.error.find("cut.ply"), std::string::npos) << y.error;
}

TEST(CloudIo, BadHeadersAreReportedWithLine) {
    const fs::path dir = TempDir();
    WriteText(dir / "nofield.pcd",
              "VERSION 0.7\nFIELDS x y\nSIZE 4 4\nTYPE F F\nWIDTH 1\nPOINTS 1\nDATA ascii\n1 2\n");
    const CloudReadResult a = ReadPcd(dir / "nofield.pcd");
    EXPECT_EQ(a.status, Status::kBadHeader);
    EXPECT_NE(a.error.find("nofield.pcd:7: FIELDS lacks one of x y z"), std::string::npos)
        << a.error;

    WriteText(dir / "count.pcd",
              "FIELDS x y z\nSIZE 4 4\nTYPE F F F\nPOINTS 1\nDATA binary\n............");
    EXPECT_EQ(ReadPcd(dir / "count.pcd").status, Status::kBadHeader);

    WriteText(dir / "big.ply", "ply\nformat binary_big_endian 1.0\nend_header\n");
    const CloudReadResult b = ReadPly(dir / "big.ply");
    EXPECT_EQ(b.status, Status::kBadHeader);
    EXPECT_NE(b.error.find("big.ply:2:"), std::string::npos) << b.error;

    WriteText(dir / "text.ply", "hello\n");
    EXPECT_EQ(ReadPly(dir / "text.ply").status, Status::kBadHeader);
    WriteText(dir / "ascii.pcd",
              "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 2\nDATA ascii\n1 2\n");
    EXPECT_EQ(ReadPcd(dir / "ascii.pcd").status, Status::kBadData);
}

TEST(CloudIo, MissingFileAndUnknownExtension) {
    const CloudReadResult missing = ReadCloud("/nonexistent/scan.pcd");
    EXPECT_EQ(missing.status, Status::kCannotOpen);
    EXPECT_NE(missing.error.find("/nonexistent/scan.pcd"), std::string::npos);
    EXPECT_EQ(ReadCloud("/tmp/scan.xyz").status, Status::kUnsupported);
}

}  // namespace
}  // namespace certislam::slam
