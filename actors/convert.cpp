// Protobuf <-> slam conversions; every decoder checks sizes and finiteness before trusting bytes.
#include "actors/convert.h"

#include <climits>
#include <cmath>
#include <cstring>
#include <map>
#include <mutex>

#include "slam/backend/rounding.h"
#include "slam/io/cloud_compression.h"

namespace certislam::actors {
namespace {

constexpr double kQuaternionNormTolerance = 1e-3;
/// A measured rotation further than this (Frobenius) from its quaternion's goes as a matrix.
constexpr double kRotationAsMatrix = 1e-14;
constexpr std::uint32_t kPointStride = sizeof(float) * 3;
constexpr std::uint32_t kMaxSweepColor = 1u << 16;  // colours a team of 65536 robots could need
static_assert(sizeof(Eigen::Vector3f) == kPointStride, "clouds must be packed float32 xyz");

/// Clouds encoded by this process, by the address of their bytes: a frame that comes back over
/// inproc points at the same bytes, and the decoder hands back the same cloud instead of a copy.
class CloudRegistry {
  public:
    void Remember(const slam::PointCloudPtr& cloud) {
        std::lock_guard lock(mutex_);
        if (++inserts_ % 256 == 0) {
            std::erase_if(clouds_, [](const auto& entry) { return entry.second.expired(); });
        }
        clouds_[cloud->data()] = cloud;
    }
    slam::PointCloudPtr Find(const std::byte* data, std::size_t points) {
        std::lock_guard lock(mutex_);
        const auto it = clouds_.find(reinterpret_cast<const void*>(data));
        if (it == clouds_.end()) return nullptr;
        auto cloud = it->second.lock();
        if (!cloud || cloud->size() != points) return nullptr;
        return cloud;
    }

  private:
    std::mutex mutex_;
    std::map<const void*, std::weak_ptr<const slam::PointCloud>> clouds_;
    std::uint64_t inserts_ = 0;
};

CloudRegistry& Registry() {
    static CloudRegistry registry;
    return registry;
}

bool AllFinite(const auto& values) {
    for (const auto v : values) {
        if (!std::isfinite(v)) return false;
    }
    return true;
}

/// Fills a CloudRef and returns the frame holding the cloud's bytes (no copy).
transport::SharedBuffer CloudFrame(const slam::PointCloudPtr& cloud, v1::CloudRef* ref) {
    const std::size_t points = cloud ? cloud->size() : 0;
    ref->set_frame_index(0);
    ref->set_point_count(points);
    ref->set_point_stride_bytes(kPointStride);
    ref->set_format(v1::POINT_FORMAT_XYZ_F32);
    ref->set_byte_length(points * kPointStride);
    if (points == 0) return transport::SharedBuffer::Copy(nullptr, 0);
    Registry().Remember(cloud);
    return transport::SharedBuffer::Wrap(cloud, reinterpret_cast<const std::byte*>(cloud->data()),
                                         points * kPointStride);
}

/// Fills a CloudRef and returns the frame holding the cloud encoded by slam/io/cloud_compression.h.
transport::SharedBuffer CompactCloudFrame(const slam::PointCloudPtr& cloud, v1::CloudRef* ref) {
    const slam::CloudEncodeResult encoded = slam::EncodeCloud(cloud ? *cloud : slam::PointCloud{});
    ref->set_frame_index(0);
    ref->set_point_count((cloud ? cloud->size() : 0) - encoded.points_dropped);
    ref->set_point_stride_bytes(0);
    ref->set_format(v1::POINT_FORMAT_XYZ_CODEC);
    ref->set_byte_length(encoded.bytes.size());
    return transport::SharedBuffer::Copy(encoded.bytes.data(), encoded.bytes.size());
}

/// The cloud of a compact frame, or nullopt when it does not decode to the declared count.
std::optional<slam::PointCloudPtr> CompactCloudOf(const transport::SharedBuffer& frame,
                                                  const v1::CloudRef& ref) {
    if (ref.byte_length() != frame.size()) return std::nullopt;
    slam::CloudDecodeResult decoded =
        slam::DecodeCloud(reinterpret_cast<const std::uint8_t*>(frame.data()), frame.size());
    if (!decoded.ok() || decoded.cloud.size() != ref.point_count()) return std::nullopt;
    return slam::PointCloudPtr(std::make_shared<slam::PointCloud>(std::move(decoded.cloud)));
}

/// The cloud a CloudRef names in a message, or nullopt when the reference does not fit.
std::optional<slam::PointCloudPtr> CloudOf(const transport::Message& message,
                                           const v1::CloudRef& ref) {
    if (ref.frame_index() >= message.frames.size()) return std::nullopt;
    if (ref.format() == v1::POINT_FORMAT_XYZ_CODEC) {
        return CompactCloudOf(message.frames[ref.frame_index()], ref);
    }
    if (ref.format() != v1::POINT_FORMAT_XYZ_F32 && ref.format() != v1::POINT_FORMAT_XYZI_F32) {
        return std::nullopt;
    }
    const std::uint64_t min_stride = ref.format() == v1::POINT_FORMAT_XYZ_F32 ? 12 : 16;
    const std::uint64_t stride = ref.point_stride_bytes();
    if (stride < min_stride || stride > 1024) return std::nullopt;
    const auto& frame = message.frames[ref.frame_index()];
    if (ref.point_count() > frame.size() / stride) return std::nullopt;
    if (ref.point_count() * stride != frame.size()) return std::nullopt;
    const std::size_t points = ref.point_count();
    if (stride == kPointStride) {
        if (auto same = Registry().Find(frame.data(), points)) return same;
    }
    auto cloud = std::make_shared<slam::PointCloud>(points);
    for (std::size_t i = 0; i < points; ++i) {
        float xyz[3];
        std::memcpy(xyz, frame.data() + i * stride, sizeof(xyz));
        if (!std::isfinite(xyz[0]) || !std::isfinite(xyz[1]) || !std::isfinite(xyz[2])) {
            return std::nullopt;
        }
        (*cloud)[i] = Eigen::Vector3f(xyz[0], xyz[1], xyz[2]);
    }
    return slam::PointCloudPtr(std::move(cloud));
}

}  // namespace

v1::Header MakeHeader(int robot_id, std::uint64_t sequence, std::int64_t stamp_ns) {
    v1::Header header;
    header.set_robot_id(static_cast<std::uint32_t>(robot_id));
    header.set_sequence(sequence);
    header.set_stamp_ns(stamp_ns);
    return header;
}

v1::PoseId ToProto(const slam::PoseId& id) {
    v1::PoseId out;
    out.set_robot_id(static_cast<std::uint32_t>(id.robot));
    out.set_index(static_cast<std::uint64_t>(id.index));
    return out;
}

std::optional<slam::PoseId> FromProto(const v1::PoseId& id) {
    if (id.robot_id() > static_cast<std::uint32_t>(INT_MAX)) return std::nullopt;
    if (id.index() > static_cast<std::uint64_t>(INT_MAX)) return std::nullopt;
    return slam::PoseId{static_cast<int>(id.robot_id()), static_cast<int>(id.index())};
}

v1::Pose3 ToProto(const Eigen::Isometry3d& T) {
    const Eigen::Quaterniond q(T.linear());
    v1::Pose3 out;
    out.set_qw(q.w());
    out.set_qx(q.x());
    out.set_qy(q.y());
    out.set_qz(q.z());
    out.set_tx_m(T.translation().x());
    out.set_ty_m(T.translation().y());
    out.set_tz_m(T.translation().z());
    return out;
}

std::optional<Eigen::Isometry3d> FromProto(const v1::Pose3& pose) {
    const double values[] = {pose.qw(),   pose.qx(),   pose.qy(),  pose.qz(),
                             pose.tx_m(), pose.ty_m(), pose.tz_m()};
    if (!AllFinite(values)) return std::nullopt;
    Eigen::Quaterniond q(pose.qw(), pose.qx(), pose.qy(), pose.qz());
    if (std::abs(q.norm() - 1.0) > kQuaternionNormTolerance) return std::nullopt;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = q.normalized().toRotationMatrix();
    T.translation() = Eigen::Vector3d(pose.tx_m(), pose.ty_m(), pose.tz_m());
    return T;
}

transport::Message EncodeKeyframe(const slam::Keyframe& keyframe, std::uint64_t sequence) {
    v1::Keyframe proto;
    *proto.mutable_header() = MakeHeader(keyframe.robot, sequence, keyframe.stamp_ns);
    *proto.mutable_pose_id() = ToProto(slam::PoseId{keyframe.robot, keyframe.index});
    *proto.mutable_t_odom_base() = ToProto(keyframe.T_odom_sensor);
    auto frame = CloudFrame(keyframe.cloud, proto.mutable_cloud());
    return transport::Pack(proto, {std::move(frame)});
}

std::optional<slam::Keyframe> DecodeKeyframe(const transport::Message& message) {
    const auto proto = transport::Unpack<v1::Keyframe>(message);
    if (!proto || !proto->has_pose_id() || !proto->has_t_odom_base()) return std::nullopt;
    const auto id = FromProto(proto->pose_id());
    const auto pose = FromProto(proto->t_odom_base());
    if (!id || !pose) return std::nullopt;
    auto cloud = CloudOf(message, proto->cloud());
    if (!cloud) return std::nullopt;
    slam::Keyframe keyframe;
    keyframe.robot = id->robot;
    keyframe.index = id->index;
    keyframe.stamp_ns = proto->header().stamp_ns();
    keyframe.T_odom_sensor = *pose;
    keyframe.cloud = std::move(*cloud);
    return keyframe;
}

transport::Message EncodeCloudReply(const v1::CloudReply& header_fields,
                                    const slam::PointCloudPtr& cloud, CloudWire wire) {
    v1::CloudReply proto = header_fields;
    proto.set_found(cloud != nullptr);
    auto frame = wire == CloudWire::kCompact ? CompactCloudFrame(cloud, proto.mutable_cloud())
                                             : CloudFrame(cloud, proto.mutable_cloud());
    return transport::Pack(proto, {std::move(frame)});
}

std::optional<slam::PointCloudPtr> DecodeCloudReply(const transport::Message& message,
                                                    v1::CloudReply* reply) {
    const auto proto = transport::Unpack<v1::CloudReply>(message);
    if (!proto || !proto->found()) return std::nullopt;
    if (reply != nullptr) *reply = *proto;
    return CloudOf(message, proto->cloud());
}

namespace {

/// The rotation_3x3 of a loop (empty: identity, unused); nullopt when it has not 9 finite values
/// or is larger than a rotation of a quaternion within the norm tolerance (||R~||_F <= 3^0.5 q^2).
std::optional<Eigen::Matrix3d> MeasuredRotation(const v1::LoopClosure& loop) {
    if (loop.rotation_3x3_size() == 0) return Eigen::Matrix3d::Identity();
    if (loop.rotation_3x3_size() != 9 || !AllFinite(loop.rotation_3x3())) return std::nullopt;
    const Eigen::Matrix3d R =
        Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(loop.rotation_3x3().data());
    const double largest = std::sqrt(3.0) * std::pow(1.0 + kQuaternionNormTolerance, 2);
    if (!(R.norm() <= largest)) return std::nullopt;
    return R;
}

}  // namespace

v1::LoopClosure ToProto(const slam::LoopClosure& loop) {
    v1::LoopClosure out;
    *out.mutable_pose_a() = ToProto(loop.a);
    *out.mutable_pose_b() = ToProto(loop.b);
    // The pose's quaternion is the nearest rotation's; a measured R~ that is not it goes beside.
    Eigen::Isometry3d T = loop.T_a_b;
    T.linear() = slam::ProjectToRotation(loop.T_a_b.linear());
    *out.mutable_t_a_b() = ToProto(T);
    const Eigen::Quaterniond q(out.t_a_b().qw(), out.t_a_b().qx(), out.t_a_b().qy(),
                               out.t_a_b().qz());
    if ((q.toRotationMatrix() - loop.T_a_b.linear()).norm() > kRotationAsMatrix) {
        const Eigen::Matrix<double, 3, 3, Eigen::RowMajor> R = loop.T_a_b.linear();
        out.mutable_rotation_3x3()->Add(R.data(), R.data() + 9);
    }
    out.mutable_information()->set_kappa(loop.kappa);
    out.mutable_information()->set_tau(loop.tau);
    out.set_fitness_rmse_m(static_cast<float>(std::sqrt(std::max(0.0, loop.fitness))));
    return out;
}

std::optional<slam::LoopClosure> FromProto(const v1::LoopClosure& loop) {
    const auto a = FromProto(loop.pose_a());
    const auto b = FromProto(loop.pose_b());
    const auto T = FromProto(loop.t_a_b());
    const double kappa = loop.information().kappa();
    const double tau = loop.information().tau();
    if (!a || !b || !T || !loop.has_t_a_b() || *a == *b) return std::nullopt;
    if (!(kappa > 0.0) || !(tau > 0.0) || !std::isfinite(kappa) || !std::isfinite(tau)) {
        return std::nullopt;
    }
    const auto R = MeasuredRotation(loop);
    if (!R) return std::nullopt;
    slam::LoopClosure out;
    out.a = *a;
    out.b = *b;
    out.T_a_b = *T;
    if (loop.rotation_3x3_size() > 0) out.T_a_b.linear() = *R;
    out.kappa = kappa;
    out.tau = tau;
    out.fitness = static_cast<double>(loop.fitness_rmse_m()) * loop.fitness_rmse_m();
    return out;
}

v1::PublicPoses ToProto(const certify::PoseBlocks& poses) {
    v1::PublicPoses out;
    out.set_iteration(poses.iteration);
    out.set_rank_r(static_cast<std::uint32_t>(poses.blocks.rows()));
    out.set_dimension_d(3);
    out.set_staircase_level(static_cast<std::uint32_t>(poses.staircase_level));
    out.set_team_round(poses.team_round);
    out.set_sweep_color(static_cast<std::uint32_t>(poses.sweep_color));
    for (const auto& id : poses.ids) *out.add_pose_ids() = ToProto(id);
    for (const auto& e : poses.edges) *out.add_boundary_edges() = ToProto(e);
    // Column-major: block k's r x 4 values are contiguous.
    out.mutable_blocks()->Assign(poses.blocks.data(), poses.blocks.data() + poses.blocks.size());
    return out;
}

std::optional<certify::PoseBlocks> FromProto(const v1::PublicPoses& poses) {
    const std::uint32_t r = poses.rank_r();
    if (poses.dimension_d() != 3 || r < 3 || r > 64) return std::nullopt;
    const auto count = static_cast<std::size_t>(poses.pose_ids_size());
    if (static_cast<std::size_t>(poses.blocks_size()) != count * r * 4) return std::nullopt;
    if (!AllFinite(poses.blocks())) return std::nullopt;
    // A greedy colouring needs at most one colour more than a robot has neighbours.
    if (poses.sweep_color() > kMaxSweepColor) return std::nullopt;
    certify::PoseBlocks out;
    for (const auto& id : poses.pose_ids()) {
        const auto parsed = FromProto(id);
        if (!parsed) return std::nullopt;
        out.ids.push_back(*parsed);
    }
    for (const auto& e : poses.boundary_edges()) {
        auto edge = FromProto(e);
        if (!edge) return std::nullopt;
        out.edges.push_back(std::move(*edge));
    }
    out.blocks = Eigen::Map<const Eigen::MatrixXd>(poses.blocks().data(), r,
                                                   static_cast<Eigen::Index>(4 * count));
    out.iteration = poses.iteration();
    out.staircase_level = static_cast<int>(poses.staircase_level());
    out.team_round = poses.team_round();
    out.sweep_color = static_cast<int>(poses.sweep_color());
    return out;
}

v1::LoopClosure LoopWithdrawal(const slam::PoseId& a, const slam::PoseId& b) {
    v1::LoopClosure out;
    *out.mutable_pose_a() = ToProto(a);
    *out.mutable_pose_b() = ToProto(b);
    *out.mutable_t_a_b() = ToProto(Eigen::Isometry3d::Identity());
    out.mutable_information()->set_kappa(0.0);
    out.mutable_information()->set_tau(0.0);
    return out;
}

std::optional<std::pair<slam::PoseId, slam::PoseId>> WithdrawnEnds(const v1::LoopClosure& loop) {
    if (loop.information().kappa() != 0.0 || loop.information().tau() != 0.0) return std::nullopt;
    const auto a = FromProto(loop.pose_a());
    const auto b = FromProto(loop.pose_b());
    if (!a || !b || *a == *b) return std::nullopt;
    return std::make_pair(*a, *b);
}

v1::TrajectoryUpdate TrajectoryToProto(int robot, const std::vector<Eigen::Isometry3d>& poses,
                                       bool certified, std::uint64_t iteration) {
    v1::TrajectoryUpdate out;
    out.set_iteration(iteration);
    out.set_certified(certified);
    for (size_t k = 0; k < poses.size(); ++k) {
        *out.add_pose_ids() = ToProto(slam::PoseId{robot, static_cast<int>(k)});
        *out.add_t_world_base() = ToProto(poses[k]);
    }
    return out;
}

std::optional<std::map<slam::PoseId, Eigen::Isometry3d>> TrajectoryFromProto(
    const v1::TrajectoryUpdate& update) {
    if (update.pose_ids_size() != update.t_world_base_size()) return std::nullopt;
    std::map<slam::PoseId, Eigen::Isometry3d> out;
    for (int k = 0; k < update.pose_ids_size(); ++k) {
        const auto id = FromProto(update.pose_ids(k));
        const auto T = FromProto(update.t_world_base(k));
        if (!id || !T) return std::nullopt;
        out[*id] = *T;
    }
    return out;
}

}  // namespace certislam::actors
