// Mesh helpers and the generated marching-cubes case table.
//
// Rather than pasting the classic 256 x 16 triangle table, the cases are derived once from two
// rules on the cube's faces, which makes the watertightness argument local and checkable:
//  1. On each face, the edges whose end corners differ in sign are joined in pairs by segments;
//     a face with four crossings (the ambiguous face) joins the two edges around each inside
//     corner. The rule depends only on the face's four corner values, so the two cubes sharing
//     a face draw the same segments there: no cracks between cubes.
//  2. Each segment is directed so that, seen from outside the cube, the inside corners lie on
//     a fixed side. Every crossing edge then starts one segment and ends another, the segments
//     close into loops, and each loop is fanned into triangles with a consistent winding.
#include "slam/mapping/mesh.h"

#include "slam/core/check.h"

namespace certislam::slam {
namespace {

using CaseTable = std::array<std::vector<std::array<std::uint8_t, 3>>, 256>;

Eigen::Vector3d CornerPosition(int c) {
    return {double(c & 1), double((c >> 1) & 1), double(c >> 2)};
}

// The two axes other than `axis`, in increasing order.
std::array<int, 2> OtherAxes(int axis) {
    return axis == 0 ? std::array{1, 2} : (axis == 1 ? std::array{0, 2} : std::array{0, 1});
}

int EdgeBetween(int a, int b) {
    for (int e = 0; e < 12; ++e) {
        if ((CubeEdgeBase(e) == a && CubeEdgeTip(e) == b) ||
            (CubeEdgeBase(e) == b && CubeEdgeTip(e) == a)) {
            return e;
        }
    }
    CERTISLAM_CHECK(false);
    return -1;
}

Eigen::Vector3d EdgeMidpoint(int e) {
    return 0.5 * (CornerPosition(CubeEdgeBase(e)) + CornerPosition(CubeEdgeTip(e)));
}

// Adds the directed segment between crossing edges a and b on a face with outward normal n;
// `inside_point` is any point on the inside side of the segment (rule 2).
void AddSegment(int a, int b, const Eigen::Vector3d& n, const Eigen::Vector3d& inside_point,
                std::array<int, 12>* next) {
    const Eigen::Vector3d p = EdgeMidpoint(a);
    const Eigen::Vector3d d = EdgeMidpoint(b) - p;
    if (n.cross(d).dot(inside_point - p) < 0.0) {
        (*next)[a] = b;
    } else {
        (*next)[b] = a;
    }
}

// Rule 1 on one face: corners in cyclic order, crossing edges paired.
void FaceSegments(int case_index, int axis, int side, std::array<int, 12>* next) {
    const auto [u, v] = OtherAxes(axis);
    const int base = side << axis;
    const std::array<int, 4> cyc = {base, base | (1 << u), base | (1 << u) | (1 << v),
                                    base | (1 << v)};
    auto inside = [&](int c) { return ((case_index >> c) & 1) != 0; };
    Eigen::Vector3d n = Eigen::Vector3d::Zero();
    n[axis] = side == 1 ? 1.0 : -1.0;
    std::array<int, 4> crossing{};  // crossing[i]: edge between cyc[i] and cyc[i+1], or -1
    int count = 0;
    for (int i = 0; i < 4; ++i) {
        const int a = cyc[i], b = cyc[(i + 1) % 4];
        crossing[i] = inside(a) != inside(b) ? EdgeBetween(a, b) : -1;
        count += crossing[i] >= 0 ? 1 : 0;
    }
    if (count == 4) {  // ambiguous face: cut off each inside corner
        const int first = inside(cyc[0]) ? 0 : 1;
        for (int k = first; k < 4; k += 2) {
            AddSegment(crossing[(k + 3) % 4], crossing[k], n, CornerPosition(cyc[k]), next);
        }
        return;
    }
    if (count != 2) return;
    std::array<int, 2> idx{};
    int m = 0;
    for (int i = 0; i < 4; ++i) {
        if (crossing[i] >= 0) idx[m++] = i;
    }
    Eigen::Vector3d inside_point = Eigen::Vector3d::Zero();
    int inside_count = 0;
    for (int c : cyc) {
        if (inside(c)) {
            inside_point += CornerPosition(c);
            ++inside_count;
        }
    }
    AddSegment(crossing[idx[0]], crossing[idx[1]], n, inside_point / inside_count, next);
}

CaseTable BuildCaseTable() {
    CaseTable table;
    for (int ci = 0; ci < 256; ++ci) {
        std::array<int, 12> next;
        next.fill(-1);
        for (int axis = 0; axis < 3; ++axis) {
            for (int side = 0; side < 2; ++side) FaceSegments(ci, axis, side, &next);
        }
        std::array<bool, 12> used{};
        for (int start = 0; start < 12; ++start) {
            if (next[start] < 0 || used[start]) continue;
            std::vector<int> loop;
            for (int e = start; !used[e]; e = next[e]) {
                CERTISLAM_CHECK(next[e] >= 0);
                used[e] = true;
                loop.push_back(e);
            }
            CERTISLAM_CHECK(loop.size() >= 3);
            for (size_t i = 1; i + 1 < loop.size(); ++i) {
                table[ci].push_back(
                    {std::uint8_t(loop[0]), std::uint8_t(loop[i]), std::uint8_t(loop[i + 1])});
            }
        }
    }
    return table;
}

}  // namespace

int CubeEdgeBase(int edge) {
    const int axis = edge / 4, k = edge % 4;
    const auto [u, v] = OtherAxes(axis);
    return ((k & 1) << u) | (((k >> 1) & 1) << v);
}

int CubeEdgeTip(int edge) { return CubeEdgeBase(edge) | (1 << (edge / 4)); }

const std::vector<std::array<std::uint8_t, 3>>& CubeCaseTriangles(int case_index) {
    static const CaseTable table = BuildCaseTable();
    CERTISLAM_CHECK(case_index >= 0 && case_index < 256);
    return table[case_index];
}

TriangleMesh TransformMesh(const TriangleMesh& mesh, const Eigen::Isometry3d& T_a_b) {
    TriangleMesh out;
    out.triangles = mesh.triangles;
    out.vertices.reserve(mesh.vertices.size());
    for (const auto& v : mesh.vertices) {
        out.vertices.push_back((T_a_b * v.cast<double>()).cast<float>());
    }
    return out;
}

std::vector<Eigen::Vector3f> VertexNormals(const TriangleMesh& mesh) {
    std::vector<Eigen::Vector3f> n(mesh.vertices.size(), Eigen::Vector3f::Zero());
    for (const auto& t : mesh.triangles) {
        const Eigen::Vector3f& a = mesh.vertices[t[0]];
        // Twice the area times the unit normal: larger triangles weigh more.
        const Eigen::Vector3f area = (mesh.vertices[t[1]] - a).cross(mesh.vertices[t[2]] - a);
        for (int k = 0; k < 3; ++k) n[t[k]] += area;
    }
    for (auto& v : n) {
        if (v.squaredNorm() > 0.0f) v.normalize();
    }
    return n;
}

void AppendMesh(const TriangleMesh& part, TriangleMesh* mesh) {
    const int offset = static_cast<int>(mesh->vertices.size());
    mesh->vertices.insert(mesh->vertices.end(), part.vertices.begin(), part.vertices.end());
    mesh->triangles.reserve(mesh->triangles.size() + part.triangles.size());
    for (const auto& t : part.triangles) mesh->triangles.push_back(t.array() + offset);
}

}  // namespace certislam::slam
