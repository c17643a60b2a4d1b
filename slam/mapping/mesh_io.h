// Writers of meshes and surface point clouds as binary PLY (opened by MeshLab, CloudCompare).
#pragma once

#include <string>

#include "slam/mapping/mesh.h"

namespace certislam::slam {

/// Writes `mesh` as binary_little_endian PLY: vertex float x y z, face list uchar int
/// vertex_indices. Returns an error text naming the file, or "" on success.
std::string WriteMeshPly(const std::string& path, const TriangleMesh& mesh);

/// Writes the mesh's vertices as a point cloud (binary_little_endian PLY, vertex float x y z
/// nx ny nz; normals from VertexNormals). Returns an error text naming the file, or "".
std::string WriteSurfacePointsPly(const std::string& path, const TriangleMesh& mesh);

}  // namespace certislam::slam
