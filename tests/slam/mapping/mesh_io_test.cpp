// Tests of the PLY writers: a TSDF mesh written, read back byte by byte (header, counts,
// records) and by the independent cloud reader; surface points with outward normals.
#include "slam/mapping/mesh_io.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "slam/io/cloud_io.h"
#include "slam/mapping/tsdf.h"
#include "tests/slam/mapping/tsdf_test_scenes.h"

namespace certislam::slam {
namespace {

constexpr double kGround = -1.7;  // between voxel layers at 0.2 m
// Projective TSDF vertices on a plane scatter by ~0.2 voxel (RMS), so normals tilt.
constexpr float kUprightMinZ = 0.9f;      // n.z of an upright normal on the open ground (< 26 deg)
constexpr double kUprightFraction = 0.9;  // of the ground vertices (patch borders tilt)

TriangleMesh SceneMesh() {
    TsdfVolume volume{TsdfConfig{}};
    for (const auto& T : {testing::Pose(0, -2, 0, 0.0), testing::Pose(9, -1, 0, 2.0)}) {
        volume.Integrate(testing::ScanBoxes(testing::GroundAndCube(kGround), T), T);
    }
    return volume.ExtractMesh();
}

std::string TempPath(const std::string& name) {
    return (std::filesystem::temp_directory_path() /
            ("certislam_mesh_io_" + std::to_string(::getpid()) + "_" + name))
        .string();
}

// Splits a PLY file into its header lines and the bytes after end_header.
void ReadPlyFile(const std::string& path, std::vector<std::string>* header, std::string* body) {
    std::ifstream in(path, std::ios::binary);
    ASSERT_TRUE(in) << path;
    std::string line;
    while (std::getline(in, line)) {
        header->push_back(line);
        if (line == "end_header") break;
    }
    std::ostringstream rest;
    rest << in.rdbuf();
    *body = rest.str();
}

TEST(MeshIo, BinaryPlyMeshReadsBackWithHeaderCountsAndRecords) {
    const TriangleMesh mesh = SceneMesh();
    ASSERT_GT(mesh.triangles.size(), 1000u);
    const std::string path = TempPath("mesh.ply");
    ASSERT_EQ(WriteMeshPly(path, mesh), "");

    std::vector<std::string> header;
    std::string body;
    ReadPlyFile(path, &header, &body);
    const std::vector<std::string> expected = {
        "ply",
        "format binary_little_endian 1.0",
        "comment certislam TSDF mesh, metres",
        "element vertex " + std::to_string(mesh.vertices.size()),
        "property float x",
        "property float y",
        "property float z",
        "element face " + std::to_string(mesh.triangles.size()),
        "property list uchar int vertex_indices",
        "end_header"};
    EXPECT_EQ(header, expected);
    ASSERT_EQ(body.size(), mesh.vertices.size() * 12 + mesh.triangles.size() * 13);
    for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
        float xyz[3];
        std::memcpy(xyz, body.data() + 12 * i, sizeof xyz);
        ASSERT_EQ(Eigen::Vector3f(xyz[0], xyz[1], xyz[2]), mesh.vertices[i]);
    }
    const char* faces = body.data() + 12 * mesh.vertices.size();
    for (std::size_t i = 0; i < mesh.triangles.size(); ++i) {
        ASSERT_EQ(faces[13 * i], 3);
        std::int32_t idx[3];
        std::memcpy(idx, faces + 13 * i + 1, sizeof idx);
        ASSERT_EQ(Eigen::Vector3i(idx[0], idx[1], idx[2]), mesh.triangles[i]);
    }
    // The project's general PLY reader (another parser) sees the same vertices.
    const CloudReadResult cloud = ReadPly(path);
    ASSERT_TRUE(cloud.ok()) << cloud.error;
    EXPECT_EQ(cloud.cloud, mesh.vertices);
    std::filesystem::remove(path);
}

TEST(MeshIo, SurfacePointsCarryOutwardNormals) {
    const TriangleMesh mesh = SceneMesh();
    const std::string path = TempPath("points.ply");
    ASSERT_EQ(WriteSurfacePointsPly(path, mesh), "");
    std::vector<std::string> header;
    std::string body;
    ReadPlyFile(path, &header, &body);
    ASSERT_GE(header.size(), 4u);
    EXPECT_EQ(header[3], "element vertex " + std::to_string(mesh.vertices.size()));
    ASSERT_EQ(body.size(), mesh.vertices.size() * 24);
    int ground = 0, upright = 0;
    for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
        float row[6];
        std::memcpy(row, body.data() + 24 * i, sizeof row);
        ASSERT_EQ(Eigen::Vector3f(row[0], row[1], row[2]), mesh.vertices[i]);
        const Eigen::Vector3f p = mesh.vertices[i];
        // Open ground away from the cube: the normal points up, out of the ground.
        if (std::abs(p.z() - kGround) < 0.05 && (p.head<2>() - Eigen::Vector2f(5, 1)).norm() > 3) {
            const Eigen::Vector3f n(row[3], row[4], row[5]);
            EXPECT_GT(n.z(), 0.0f);  // out of the ground, never into it
            upright += n.z() > kUprightMinZ ? 1 : 0;
            ++ground;
        }
    }
    EXPECT_GT(ground, 100);
    EXPECT_GT(upright, kUprightFraction * ground) << upright << " of " << ground;
    const CloudReadResult cloud = ReadPly(path);
    ASSERT_TRUE(cloud.ok()) << cloud.error;
    EXPECT_EQ(cloud.cloud.size(), mesh.vertices.size());
    std::filesystem::remove(path);
}

TEST(MeshIo, UnwritablePathIsAnErrorNamingTheFile) {
    const std::string path = "/nonexistent-dir/mesh.ply";
    const std::string error = WriteMeshPly(path, TriangleMesh{});
    EXPECT_NE(error.find(path), std::string::npos);
}

}  // namespace
}  // namespace certislam::slam
