// Triangle meshes and the marching-cubes polygonisation of one cube of signed distances.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <vector>

namespace certislam::slam {

/// An indexed triangle mesh, metres, in one frame (named by whoever holds it). Triangles are
/// wound counter-clockwise seen from the free-space side (normals point out of the surface).
struct TriangleMesh {
    std::vector<Eigen::Vector3f> vertices;   ///< vertex positions
    std::vector<Eigen::Vector3i> triangles;  ///< three vertex indices per triangle
};

/// Returns `mesh` with every vertex mapped by `T_a_b` (mesh given in frame b, result in a).
TriangleMesh TransformMesh(const TriangleMesh& mesh, const Eigen::Isometry3d& T_a_b);

/// Unit vertex normals: the area-weighted sum of the adjacent triangles' normals (pointing to
/// the free-space side); zero for a vertex in no triangle.
std::vector<Eigen::Vector3f> VertexNormals(const TriangleMesh& mesh);

/// Appends `part` to `mesh` (indices shifted); shared vertices are not merged (a union).
void AppendMesh(const TriangleMesh& part, TriangleMesh* mesh);

/// Cube corner c (0..7) sits at offset (c & 1, (c >> 1) & 1, (c >> 2) & 1) from the cube's
/// minimum corner. Edge e (0..11) runs along axis e / 4 from its base corner CubeEdgeBase(e).
int CubeEdgeBase(int edge);

/// The corner at the other end of `edge` from CubeEdgeBase(edge).
int CubeEdgeTip(int edge);

/// The marching-cubes triangles of one cube case: `case_index` has bit c set when corner c is
/// inside (negative distance). Each triangle is three cube edges whose crossings are its
/// vertices. The 256 cases are generated once from face rules (see mesh.cpp), so the surface
/// is watertight between neighbouring cubes and consistently wound.
const std::vector<std::array<std::uint8_t, 3>>& CubeCaseTriangles(int case_index);

}  // namespace certislam::slam
