// Binary PLY writers for meshes and surface points.
#include "slam/mapping/mesh_io.h"

#include <bit>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <vector>

namespace certislam::slam {
namespace {

static_assert(std::endian::native == std::endian::little, "PLY is written little-endian");
static_assert(sizeof(Eigen::Vector3f) == 3 * sizeof(float), "vertices are written as one block");

std::string Finish(std::ofstream& out, const std::string& path) {
    out.flush();
    return out ? "" : path + ": write failed";
}

}  // namespace

std::string WriteMeshPly(const std::string& path, const TriangleMesh& mesh) {
    std::ofstream out(path, std::ios::binary);
    if (!out) return path + ": cannot open for writing";
    out << "ply\nformat binary_little_endian 1.0\ncomment certislam TSDF mesh, metres\n"
        << "element vertex " << mesh.vertices.size()
        << "\nproperty float x\nproperty float y\nproperty float z\n"
        << "element face " << mesh.triangles.size()
        << "\nproperty list uchar int vertex_indices\nend_header\n";
    out.write(reinterpret_cast<const char*>(mesh.vertices.data()),
              static_cast<std::streamsize>(mesh.vertices.size() * 3 * sizeof(float)));
    // One record per face: count byte then three int32 (13 bytes, unaligned: packed by hand).
    std::vector<char> faces(mesh.triangles.size() * 13);
    char* p = faces.data();
    for (const auto& t : mesh.triangles) {
        *p++ = 3;
        const std::int32_t idx[3] = {t[0], t[1], t[2]};
        std::memcpy(p, idx, sizeof idx);
        p += sizeof idx;
    }
    out.write(faces.data(), static_cast<std::streamsize>(faces.size()));
    return Finish(out, path);
}

std::string WriteSurfacePointsPly(const std::string& path, const TriangleMesh& mesh) {
    std::ofstream out(path, std::ios::binary);
    if (!out) return path + ": cannot open for writing";
    out << "ply\nformat binary_little_endian 1.0\ncomment certislam TSDF surface points, metres\n"
        << "element vertex " << mesh.vertices.size()
        << "\nproperty float x\nproperty float y\nproperty float z\n"
        << "property float nx\nproperty float ny\nproperty float nz\nend_header\n";
    const std::vector<Eigen::Vector3f> normals = VertexNormals(mesh);
    std::vector<float> rows;
    rows.reserve(mesh.vertices.size() * 6);
    for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
        rows.insert(rows.end(), mesh.vertices[i].data(), mesh.vertices[i].data() + 3);
        rows.insert(rows.end(), normals[i].data(), normals[i].data() + 3);
    }
    out.write(reinterpret_cast<const char*>(rows.data()),
              static_cast<std::streamsize>(rows.size() * sizeof(float)));
    return Finish(out, path);
}

}  // namespace certislam::slam
