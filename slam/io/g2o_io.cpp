// g2o reader and writer. kappa/tau follow SESync::read_g2o_file (data/g2o/README.md), but blank
// lines are skipped instead of re-adding the previous edge, and malformed input is an error value.
#include "slam/io/g2o_io.h"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iomanip>
#include <numeric>
#include <sstream>
#include <string_view>
#include <vector>

namespace certislam::slam {
namespace {

using Status = PoseGraphReadResult::Status;

struct LineError {
    std::string reason;
};

std::vector<std::string> Tokenize(const std::string& line) {
    std::vector<std::string> tokens;
    std::istringstream in(line);
    std::string tok;
    while (in >> tok) tokens.push_back(tok);
    return tokens;
}

// Parses tokens[first .. first+count) as finite doubles; throws LineError otherwise.
std::vector<double> Numbers(const std::vector<std::string>& tokens, size_t first, size_t count) {
    if (tokens.size() < first + count) {
        throw LineError{"too few numbers for " + tokens[0] + " (expected " +
                        std::to_string(count + first - 1) + ", got " +
                        std::to_string(tokens.size() - 1) + ")"};
    }
    if (tokens.size() > first + count) {
        throw LineError{"too many numbers for " + tokens[0] + " (expected " +
                        std::to_string(count + first - 1) + ")"};
    }
    std::vector<double> values(count);
    for (size_t k = 0; k < count; ++k) {
        const std::string& tok = tokens[first + k];
        char* end = nullptr;
        values[k] = std::strtod(tok.c_str(), &end);
        if (end == tok.c_str() || *end != '\0') throw LineError{"not a number: '" + tok + "'"};
        if (!std::isfinite(values[k])) throw LineError{"non-finite value: '" + tok + "'"};
        if (std::abs(values[k]) > kMaxInformation) {
            throw LineError{"value '" + tok + "' is beyond +-" + std::to_string(kMaxInformation)};
        }
    }
    return values;
}

int PoseIndex(const std::string& tok) {
    char* end = nullptr;
    const long v = std::strtol(tok.c_str(), &end, 10);
    if (end == tok.c_str() || *end != '\0' || v < 0 || v > 100'000'000) {
        throw LineError{"bad pose id: '" + tok + "'"};
    }
    return static_cast<int>(v);
}

// Symmetric matrix from a row-major upper triangle of size k starting at values[offset].
Eigen::MatrixXd UpperTriangle(const std::vector<double>& values, size_t offset, int k) {
    Eigen::MatrixXd m(k, k);
    size_t idx = offset;
    for (int r = 0; r < k; ++r) {
        for (int c = r; c < k; ++c) m(r, c) = m(c, r) = values[idx++];
    }
    return m;
}

double TraceOfInverse(const Eigen::MatrixXd& block, const char* name) {
    Eigen::LLT<Eigen::MatrixXd> llt(block);
    if (llt.info() != Eigen::Success) {
        throw LineError{std::string("information block ") + name + " is not positive definite"};
    }
    const double tr = llt.solve(Eigen::MatrixXd::Identity(block.rows(), block.cols())).trace();
    if (!(tr > 0.0) || !std::isfinite(tr)) {
        throw LineError{std::string("information block ") + name + " is degenerate"};
    }
    return tr;
}

// Quaternion (qx qy qz qw) to a rotation by QuaternionRotation's rules; throws LineError.
Eigen::Matrix3d QuaternionMatrix(double qx, double qy, double qz, double qw,
                                 bool always_normalise = false) {
    std::string why;
    const auto R = QuaternionRotation(qx, qy, qz, qw, &why, always_normalise);
    if (!R) throw LineError{why};
    return *R;
}

// Throws LineError when the edge's values are out of range (CheckMeasurementRange).
RelativePoseMeasurement InRange(RelativePoseMeasurement e) {
    if (const std::string why = CheckMeasurementRange(e.t, e.kappa, e.tau); !why.empty()) {
        throw LineError{why};
    }
    return e;
}

Eigen::Matrix2d Rot2(double theta) {
    Eigen::Matrix2d R;
    R << std::cos(theta), -std::sin(theta), std::sin(theta), std::cos(theta);
    return R;
}

RelativePoseMeasurement ParseSe2Edge(const std::vector<std::string>& tok) {
    RelativePoseMeasurement e;
    if (tok.size() < 3) throw LineError{"too few numbers for EDGE_SE2 (expected 11)"};
    e.i = PoseIndex(tok[1]);
    e.j = PoseIndex(tok[2]);
    const std::vector<double> v = Numbers(tok, 3, 9);
    e.t = Eigen::Vector2d(v[0], v[1]);
    e.R = Rot2(v[2]);
    Eigen::Matrix2d tt;
    tt << v[3], v[4], v[4], v[6];
    e.tau = 2.0 / TraceOfInverse(tt, "translation");
    e.kappa = v[8];
    if (!(e.kappa > 0.0)) throw LineError{"information block rotation is not positive definite"};
    return InRange(e);
}

RelativePoseMeasurement ParseSe3Edge(const std::vector<std::string>& tok) {
    RelativePoseMeasurement e;
    if (tok.size() < 3) throw LineError{"too few numbers for EDGE_SE3:QUAT (expected 30)"};
    e.i = PoseIndex(tok[1]);
    e.j = PoseIndex(tok[2]);
    const std::vector<double> v = Numbers(tok, 3, 28);
    e.t = Eigen::Vector3d(v[0], v[1], v[2]);
    e.R = QuaternionMatrix(v[3], v[4], v[5], v[6]);
    const Eigen::MatrixXd omega = UpperTriangle(v, 7, 6);
    e.tau = 3.0 / TraceOfInverse(omega.topLeftCorner(3, 3), "translation");
    e.kappa = 3.0 / (2.0 * TraceOfInverse(omega.bottomRightCorner(3, 3), "rotation"));
    return InRange(e);
}

struct Vertex {
    int id;
    Eigen::MatrixXd R;
    Eigen::VectorXd t;
};

Vertex ParseVertex(const std::vector<std::string>& tok, int d) {
    if (tok.size() < 2) throw LineError{"too few numbers for " + tok[0]};
    Vertex v{PoseIndex(tok[1]), {}, {}};
    if (d == 2) {
        const std::vector<double> x = Numbers(tok, 2, 3);
        v.t = Eigen::Vector2d(x[0], x[1]);
        v.R = Rot2(x[2]);
    } else {
        const std::vector<double> x = Numbers(tok, 2, 7);
        v.t = Eigen::Vector3d(x[0], x[1], x[2]);
        v.R = QuaternionMatrix(x[3], x[4], x[5], x[6], /*always_normalise=*/true);  // a guess
    }
    if (v.t.cwiseAbs().maxCoeff() > kMaxTranslation) {
        throw LineError{"translation beyond +-" + std::to_string(kMaxTranslation) + " m"};
    }
    return v;
}

// Handles one non-blank line; throws LineError on malformed input.
void ParseLine(const std::vector<std::string>& tok, int* dim, PoseGraph* graph,
               std::vector<Vertex>* vertices) {
    const std::string& kind = tok[0];
    int line_dim = 0;
    if (kind == "EDGE_SE2" || kind == "VERTEX_SE2") line_dim = 2;
    if (kind == "EDGE_SE3:QUAT" || kind == "VERTEX_SE3:QUAT") line_dim = 3;
    if (kind == "FIX") {
        if (tok.size() < 2) throw LineError{"too few numbers for FIX"};
        for (size_t k = 1; k < tok.size(); ++k) PoseIndex(tok[k]);
        return;
    }
    if (line_dim == 0) throw LineError{"unknown token '" + kind + "'"};
    if (*dim != 0 && *dim != line_dim) {
        throw LineError{"'" + kind + "' mixes 2D and 3D in one file"};
    }
    *dim = line_dim;
    if (kind == "EDGE_SE2") graph->edges.push_back(ParseSe2Edge(tok));
    if (kind == "EDGE_SE3:QUAT") graph->edges.push_back(ParseSe3Edge(tok));
    if (kind.rfind("VERTEX", 0) == 0) vertices->push_back(ParseVertex(tok, line_dim));
}

PoseGraphReadResult Fail(Status status, std::string error) {
    PoseGraphReadResult r;
    r.status = status;
    r.error = std::move(error);
    return r;
}

void FillInitialGuess(const std::vector<Vertex>& vertices, PoseGraph* graph) {
    const int d = graph->d;
    PoseMatrix guess = PoseMatrix::Zero(d, (d + 1) * graph->n);
    std::vector<bool> seen(graph->n, false);
    for (const Vertex& v : vertices) {
        if (v.id >= graph->n) return;  // a vertex no edge touches: no usable guess
        guess.block(0, BlockColumn(v.id, d), d, d) = v.R;
        guess.col(BlockColumn(v.id, d) + d) = v.t;
        seen[v.id] = true;
    }
    if (std::find(seen.begin(), seen.end(), false) == seen.end()) graph->initial_guess = guess;
}

}  // namespace

bool IsConnected(const PoseGraph& graph) {
    if (graph.n < 1) return false;
    std::vector<int> parent(graph.n);
    std::iota(parent.begin(), parent.end(), 0);
    auto find = [&](int x) {
        while (parent[x] != x) x = parent[x] = parent[parent[x]];
        return x;
    };
    int components = graph.n;
    for (const auto& e : graph.edges) {
        const int a = find(e.i);
        const int b = find(e.j);
        if (a != b) {
            parent[a] = b;
            --components;
        }
    }
    return components == 1;
}

PoseGraphReadResult ReadG2oStream(std::istream& in, const std::string& name) {
    PoseGraphReadResult result;
    PoseGraph& graph = result.graph;
    std::vector<Vertex> vertices;
    int dim = 0;
    int line_no = 0;
    std::string line;
    while (std::getline(in, line)) {
        ++line_no;
        const std::vector<std::string> tok = Tokenize(line);
        if (tok.empty() || tok[0][0] == '#') continue;  // blank line: skipped, nothing re-added
        try {
            ParseLine(tok, &dim, &graph, &vertices);
        } catch (const LineError& e) {
            return Fail(Status::kParseError,
                        name + ":" + std::to_string(line_no) + ": " + e.reason);
        }
    }
    graph.d = dim == 0 ? 3 : dim;
    for (const auto& e : graph.edges) graph.n = std::max({graph.n, e.i + 1, e.j + 1});
    if (graph.edges.empty()) return Fail(Status::kDisconnected, name + ": no edges");
    // A connected graph has n <= edges + 1: checked before allocating per-pose arrays.
    if (static_cast<std::size_t>(graph.n) > graph.edges.size() + 1 || !IsConnected(graph)) {
        return Fail(Status::kDisconnected, name + ": graph is not connected (" +
                                               std::to_string(graph.n) + " poses, " +
                                               std::to_string(graph.edges.size()) + " edges)");
    }
    graph.ids.resize(graph.n);
    for (int g = 0; g < graph.n; ++g) graph.ids[g] = PoseId{0, g};
    FillInitialGuess(vertices, &graph);
    return result;
}

std::optional<Eigen::Matrix3d> QuaternionRotation(double qx, double qy, double qz, double qw,
                                                  std::string* why, bool always_normalise) {
    const Eigen::Quaterniond q(qw, qx, qy, qz);
    const double norm = q.norm();
    if (!always_normalise && std::abs(norm - 1.0) <= kQuaternionRounding) {
        return q.toRotationMatrix();  // as written (SE-Sync's convention for the benchmarks)
    }
    if (!(std::abs(norm - 1.0) <= kQuaternionNormTolerance)) {
        std::ostringstream out;
        out << "quaternion norm " << std::setprecision(9) << norm << " is not within "
            << kQuaternionNormTolerance << " of 1 (not a rotation)";
        *why = out.str();
        return std::nullopt;
    }
    return q.normalized().toRotationMatrix();
}

std::string CheckMeasurementRange(const Eigen::VectorXd& t, double kappa, double tau) {
    if (!t.allFinite() || t.cwiseAbs().maxCoeff() > kMaxTranslation) {
        return "translation beyond +-" + std::to_string(kMaxTranslation) + " m";
    }
    for (const double w : {kappa, tau}) {
        if (!(w >= kMinWeight && w <= kMaxInformation)) {
            std::ostringstream out;
            out << "weight (kappa " << kappa << ", tau " << tau << ") not in [" << kMinWeight
                << ", " << kMaxInformation << "]";
            return out.str();
        }
    }
    return "";
}

PoseGraphReadResult ReadG2o(const std::string& path) {
    std::ifstream in(path);
    if (!in) return Fail(Status::kFileError, path + ": cannot open file");
    return ReadG2oStream(in, path);
}

bool WriteG2o(const std::string& path, const PoseGraph& graph, const PoseMatrix& poses,
              std::string* error) {
    std::ofstream out(path);
    if (!out) {
        if (error) *error = path + ": cannot open file for writing";
        return false;
    }
    const int d = graph.d;
    out << std::setprecision(17);
    for (int g = 0; g < graph.n; ++g) {
        const Eigen::MatrixXd R = poses.block(0, BlockColumn(g, d), d, d);
        const Eigen::VectorXd t = poses.col(BlockColumn(g, d) + d);
        if (d == 2) {
            out << "VERTEX_SE2 " << g << ' ' << t(0) << ' ' << t(1) << ' '
                << std::atan2(R(1, 0), R(0, 0)) << '\n';
        } else {
            const Eigen::Quaterniond q{Eigen::Matrix3d(R)};
            out << "VERTEX_SE3:QUAT " << g << ' ' << t(0) << ' ' << t(1) << ' ' << t(2) << ' '
                << q.x() << ' ' << q.y() << ' ' << q.z() << ' ' << q.w() << '\n';
        }
    }
    for (const auto& e : graph.edges) {
        if (d == 2) {
            // tau = 2 / tr(diag(tau, tau)^-1), kappa = I33.
            out << "EDGE_SE2 " << e.i << ' ' << e.j << ' ' << e.t(0) << ' ' << e.t(1) << ' '
                << std::atan2(e.R(1, 0), e.R(0, 0)) << ' ' << e.tau << " 0 0 " << e.tau << " 0 "
                << e.kappa << '\n';
        } else {
            // tau = 3 / tr((tau I)^-1); kappa = 3 / (2 tr((2 kappa I)^-1)).
            const Eigen::Quaterniond q{Eigen::Matrix3d(e.R)};
            out << "EDGE_SE3:QUAT " << e.i << ' ' << e.j << ' ' << e.t(0) << ' ' << e.t(1) << ' '
                << e.t(2) << ' ' << q.x() << ' ' << q.y() << ' ' << q.z() << ' ' << q.w();
            const double diag[6] = {e.tau, e.tau, e.tau, 2 * e.kappa, 2 * e.kappa, 2 * e.kappa};
            for (int r = 0; r < 6; ++r) {
                for (int c = r; c < 6; ++c) out << ' ' << (r == c ? diag[r] : 0.0);
            }
            out << '\n';
        }
    }
    if (!out) {
        if (error) *error = path + ": write failed";
        return false;
    }
    return true;
}

}  // namespace certislam::slam
