// Reading and writing pose graphs in the g2o text format (EDGE_SE2, EDGE_SE3:QUAT, VERTEX_*).
#pragma once

#include <Eigen/Core>
#include <istream>
#include <optional>
#include <string>

#include "slam/core/pose_graph.h"

namespace certislam::slam {

/// Outcome of reading a pose-graph file. On failure `error` names file:line and the reason.
struct PoseGraphReadResult {
    enum class Status {
        kOk,            ///< `graph` holds the file's graph
        kFileError,     ///< the file could not be opened
        kParseError,    ///< a line was malformed (unknown token, too few numbers, non-finite, ...)
        kDisconnected,  ///< the parsed graph is not connected (or has no edges)
    };
    Status status = Status::kOk;
    PoseGraph graph;    ///< the graph (valid only when status == kOk)
    std::string error;  ///< "file:line: reason" (empty when status == kOk)

    /// True when the read succeeded.
    bool ok() const { return status == Status::kOk; }
};

/// Quaternions with ||q| - 1| <= this are rounding (the benchmark files print ~6 digits: |q| - 1
/// reaches 1.7e-6 in cubicle.g2o) and are used as written, as SE-Sync's C++ reader and dpgo do:
/// the published optima f* are for those unnormalised rotations (data/g2o/README.md).
inline constexpr double kQuaternionRounding = 1e-5;

/// Quaternions with kQuaternionRounding < ||q| - 1| <= this come from a low-precision writer and
/// are normalised; beyond it a line is corrupt and refused (unnormalised, |q| = 1.03 scales the
/// rotation by ~1.06 and the relaxation certifies a wrong cost; normalised, it would hide a
/// corrupt line).
inline constexpr double kQuaternionNormTolerance = 1e-3;

/// Largest |value| accepted for a translation component (m) in a pose-graph file.
inline constexpr double kMaxTranslation = 1e9;

/// Largest |value| accepted for an information-matrix entry (the benchmark files reach 2.7e12,
/// input_INTEL_g2o.g2o); kappa and tau must lie in [kMinWeight, kMaxInformation].
inline constexpr double kMaxInformation = 1e15;

/// Smallest kappa or tau accepted: a lighter edge is numerically absent yet would still tie the
/// graph together (and make the connection Laplacian singular to working precision).
inline constexpr double kMinWeight = 1e-12;

/// The rotation of quaternion (qx, qy, qz, qw): as written within kQuaternionRounding of unit norm
/// (unless `always_normalise`), normalised within kQuaternionNormTolerance; otherwise
/// std::nullopt with *why giving |q| and the rule.
std::optional<Eigen::Matrix3d> QuaternionRotation(double qx, double qy, double qz, double qw,
                                                  std::string* why, bool always_normalise = false);

/// "" when every |value| of t is within kMaxTranslation and kappa, tau are in
/// [kMinWeight, kMaxInformation]; else the rule broken.
std::string CheckMeasurementRange(const Eigen::VectorXd& t, double kappa, double tau);

/// Reads a g2o file. kappa and tau follow SE-Sync's rules (data/g2o/README.md); quaternions are
/// used as written within kQuaternionRounding of unit norm, normalised within
/// kQuaternionNormTolerance and refused beyond it (VERTEX guesses are always normalised);
/// translations beyond kMaxTranslation and information beyond kMaxInformation are refused; blank
/// lines and `#` comments are skipped; duplicate edges, multi-edges and edges with i > j are kept
/// as written; `FIX` lines are accepted and ignored; n = max id + 1. VERTEX lines fill
/// `initial_guess` when every pose has one. All poses get robot 0.
PoseGraphReadResult ReadG2o(const std::string& path);

/// Same as ReadG2o for text already open; `name` is used in error messages.
PoseGraphReadResult ReadG2oStream(std::istream& in, const std::string& name);

/// Writes `poses` (d x (d+1)n, blocks [R_g t_g]) as VERTEX lines followed by the graph's edges.
/// Edges are written with the isotropic information matrix that reproduces their kappa and tau
/// under ReadG2o's rules (the file's off-diagonal information terms are not kept). Returns false
/// and sets *error when the file cannot be written.
bool WriteG2o(const std::string& path, const PoseGraph& graph, const PoseMatrix& poses,
              std::string* error);

/// True when every pose is reached from pose 0 through the edges (and the graph has n >= 1).
bool IsConnected(const PoseGraph& graph);

}  // namespace certislam::slam
