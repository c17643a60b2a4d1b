// Conversions between the protobuf messages of proto/certislam/v1 and the slam/ and certify/
// types: the one place where the two meet. Decoders treat their input as untrusted: they return
// std::nullopt on anything malformed (the calling actor drops and counts it).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "certify/certificate.h"
#include "certify/distributed/distributed_lanczos.h"
#include "certify/pipeline/solver_state.h"
#include "certify/pipeline/team_finish.h"
#include "certislam/v1/certificate.pb.h"
#include "certislam/v1/keyframe.pb.h"
#include "certislam/v1/loop_closure.pb.h"
#include "certislam/v1/map.pb.h"
#include "certislam/v1/rbcd.pb.h"
#include "slam/core/keyframe.h"
#include "slam/core/loop_closure.h"
#include "slam/core/pose_graph.h"
#include "transport/message.h"

namespace certislam::actors {

/// A header for a message sent by `robot_id` (sequence and stamp as given).
v1::Header MakeHeader(int robot_id, std::uint64_t sequence, std::int64_t stamp_ns);

/// PoseId to the wire.
v1::PoseId ToProto(const slam::PoseId& id);
/// PoseId from the wire; nullopt when a field is outside int range.
std::optional<slam::PoseId> FromProto(const v1::PoseId& id);

/// Pose to the wire (unit quaternion + translation).
v1::Pose3 ToProto(const Eigen::Isometry3d& T);
/// Pose from the wire; nullopt when not finite or the quaternion's norm is off 1 by > 1e-3.
std::optional<Eigen::Isometry3d> FromProto(const v1::Pose3& pose);

/// A keyframe as a message: Keyframe proto in the envelope, the cloud (float32 xyz, 12-byte
/// stride) in binary frame 0 pointing at the cloud's own bytes (no copy on the way out).
transport::Message EncodeKeyframe(const slam::Keyframe& keyframe, std::uint64_t sequence);
/// The keyframe of a message; nullopt when malformed. Inside one process the cloud comes back
/// as the very PointCloudPtr that was encoded (zero-copy); otherwise it is copied once from the
/// frame into a new cloud.
std::optional<slam::Keyframe> DecodeKeyframe(const transport::Message& message);

/// How a cloud reply carries its cloud.
enum class CloudWire {
    kFloat32,  ///< float32 xyz (12-byte stride), zero-copy in-process
    kCompact,  ///< slam/io/cloud_compression.h: 1 cm steps, Morton order, zstd (order lost)
};

/// A cloud reply (found or not) for a cloud request, with the cloud in binary frame 0.
transport::Message EncodeCloudReply(const v1::CloudReply& header_fields,
                                    const slam::PointCloudPtr& cloud,
                                    CloudWire wire = CloudWire::kCompact);
/// The cloud of a CloudReply message (either wire form); nullopt when malformed or not found.
std::optional<slam::PointCloudPtr> DecodeCloudReply(const transport::Message& message,
                                                    v1::CloudReply* reply);

/// A loop closure on the wire (kappa, tau in Information6; fitness as RMSE).
v1::LoopClosure ToProto(const slam::LoopClosure& loop);
/// A loop closure back; nullopt when ids or pose are malformed or weights are not > 0.
std::optional<slam::LoopClosure> FromProto(const v1::LoopClosure& loop);

/// A withdrawal of the loop (a, b) on the wire: a LoopClosure with both ids, identity T_a_b and
/// zero weights (kappa = tau = 0, which no accepted loop has). Like an accepted loop sent by a
/// matcher, its header's stamp_ns is the matcher's verdict version (increasing; a solver's
/// re-broadcast of a loop carries 0): a receiver applies only the newest verdict per loop.
v1::LoopClosure LoopWithdrawal(const slam::PoseId& a, const slam::PoseId& b);
/// The ends (a, b) of a withdrawal message; nullopt when `loop` is not one.
std::optional<std::pair<slam::PoseId, slam::PoseId>> WithdrawnEnds(const v1::LoopClosure& loop);

/// Public poses on the wire (d = 3).
v1::PublicPoses ToProto(const certify::PoseBlocks& poses);
/// Public poses back; nullopt unless d = 3, 3 <= r <= 64 and the value count matches.
std::optional<certify::PoseBlocks> FromProto(const v1::PublicPoses& poses);

/// Poses of one robot's keyframes in its solver's (anchor robot's) frame, on the wire.
v1::TrajectoryUpdate TrajectoryToProto(int robot, const std::vector<Eigen::Isometry3d>& poses,
                                       bool certified, std::uint64_t iteration);
/// Pose id -> pose of a TrajectoryUpdate; nullopt when the lists disagree or a pose is malformed.
std::optional<std::map<slam::PoseId, Eigen::Isometry3d>> TrajectoryFromProto(
    const v1::TrajectoryUpdate& update);

/// A solver status a peer may send: robot id and staircase level fit an int, rank_r <= 64, cost and
/// gradient norm finite (the synchronous rounds sum them: one NaN would stall the team).
bool IsValidStatus(const v1::SolverStatus& status);

/// Values per pose of a distributed certificate round's vectors (d + 1 columns, d = 3).
inline constexpr std::uint32_t kCertificateBlock = 4;
/// A round's opening a certifier may act on: round > 0, 3 <= rank_r <= 64, robot ids that fit an
/// int, each robot named once.
bool IsValidRound(const v1::CertificateRound& round);
/// One robot's rows of a round's Lanczos vector (CertificateVector).
struct RoundVector {
    std::uint64_t round = 0;  ///< > 0
    int robot = 0;
    int step = 0;                   ///< Lanczos step, or LOBPCG exchange
    std::vector<slam::PoseId> ids;  ///< the sender's public poses
    Eigen::VectorXd values;  ///< kCertificateBlock finite values per id, per column (1 to 16)
};
/// A CertificateVector as a RoundVector; nullopt unless round > 0, block_size = kCertificateBlock,
/// the value count is 1 to certify::kMaxBlockSize columns of the ids' values, every value is
/// finite and the ids and step fit an int.
std::optional<RoundVector> FromProto(const v1::CertificateVector& vector);
/// One robot's partial sums of a round (CertificateReduction).
struct RoundReduction {
    std::uint64_t round = 0;  ///< > 0
    int robot = 0;
    int step = 0;                ///< Lanczos step (setup: 0)
    int stage = 0;               ///< which sum within the step
    std::vector<double> values;  ///< finite
};
/// A CertificateReduction as a RoundReduction; nullopt unless round > 0, every value is finite
/// and robot, step and stage fit an int.
std::optional<RoundReduction> FromProto(const v1::CertificateReduction& reduction);

/// A peer's share of the team's second-order finish (FinishMessage), as TeamFinish takes it.
struct FinishBody {
    v1::FinishMessage::Kind kind = v1::FinishMessage::KIND_UNSPECIFIED;
    int robot = 0;                         ///< the sender (the header's robot id)
    int to = 0;                            ///< edges, vector: the receiving robot
    std::uint64_t step = 0;                ///< vector, sums
    int staircase_level = 0;               ///< the sender's
    std::vector<slam::PoseId> ids;         ///< edges: the sender's poses; vector: the entries'
    Eigen::MatrixXd blocks;                ///< vector: r x 4|ids| (r x 0 when ids is empty)
    std::vector<double> values;            ///< sums (a failing robot's share is not finite)
    std::vector<slam::LoopClosure> edges;  ///< edges
};
/// A FinishMessage as a FinishBody; nullopt unless the kind is known, robot ids and level fit an
/// int, a vector's 1 <= rank_r <= 64 and its value count is rank_r * 4 per id, and every id and
/// edge decodes. The finish itself checks steps, ranks, finiteness and whose poses they are.
std::optional<FinishBody> FromProto(const v1::FinishMessage& message);
/// One robot's finish output on the wire (header, session and level are the sender's to stamp).
v1::FinishMessage ToProto(const certify::FinishEdges& edges);
v1::FinishMessage ToProto(const certify::FinishVector& vector);
v1::FinishMessage ToProto(const certify::FinishSums& sums);

/// Largest uncompressed submap a peer's MapUpdate may claim.
inline constexpr std::uint64_t kMaxSubmapBytes = 1ull << 30;
/// A peer's submap update as the mapper uses it.
struct MapBody {
    int sender = 0;       ///< the robot whose submap it is (the header's robot id)
    int submap = 0;       ///< the submap's index among the sender's
    slam::PoseId anchor;  ///< the sender's keyframe the submap hangs from
    Eigen::Isometry3d T_world_anchor = Eigen::Isometry3d::Identity();
    std::optional<std::string> bytes;  ///< the submap's serialised TSDF; nullopt: moved only
};
/// A MapUpdate message as a MapBody; nullopt unless the anchor is the sender's and a rigid pose,
/// ids fit an int, and a payload (kind TSDF blocks) is its frame's whole length and decompresses
/// (none or zstd) to its declared size, at most kMaxSubmapBytes.
std::optional<MapBody> DecodeMapUpdate(const transport::Message& message);

/// A certificate's verdict and quantities as a report.
v1::CertificateReport ToProto(const certify::CertificateResult& result, std::uint32_t rank);
/// The verdict a certificate status maps to.
v1::CertificateVerdict VerdictOf(certify::CertificateResult::Status status);
/// The one spelling of a report's verdict: certify::VerdictName of the status it came from
/// ("certified", "not optimal", "not critical", "inconclusive"), or "none" (no certificate).
std::string VerdictName(v1::CertificateVerdict verdict);

}  // namespace certislam::actors
