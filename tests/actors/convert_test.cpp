// Conversions: slam types survive a round trip through real protobuf bytes and ZeroMQ frames; the
// cloud is not copied inside a process; malformed messages decode to nothing.
#include "actors/convert.h"
#include "actors/convert_descriptor.h"

#include <gtest/gtest.h>

#include <cmath>

#include <random>

#include "certislam/v1/control.pb.h"

namespace certislam::actors {
namespace {

constexpr double kPoseTolerance = 1e-12;

slam::Keyframe MakeKeyframe(int points) {
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> u(-50.0f, 50.0f);
    auto cloud = std::make_shared<slam::PointCloud>();
    for (int i = 0; i < points; ++i) cloud->emplace_back(u(rng), u(rng), u(rng));
    slam::Keyframe kf;
    kf.robot = 2;
    kf.index = 17;
    kf.stamp_ns = 1234567890123;
    kf.T_odom_sensor.linear() =
        Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
    kf.T_odom_sensor.translation() = Eigen::Vector3d(4.5, -3.25, 0.125);
    kf.cloud = cloud;
    return kf;
}

/// Through real ZeroMQ frame bytes: encode, copy every frame's bytes, decode.
transport::Message OverTheWire(const transport::Message& message) {
    auto frames = transport::Encode(message);
    std::vector<zmq::message_t> copies;
    for (auto& f : frames) copies.emplace_back(f.data(), f.size());
    auto decoded = transport::Decode(std::move(copies));
    EXPECT_EQ(decoded.status, transport::DecodeResult::Status::kOk) << decoded.detail;
    return std::move(*decoded.message);
}

TEST(Convert, KeyframeRoundTripsThroughBytesWithCloudCopiedOnce) {
    const auto kf = MakeKeyframe(5000);
    const auto message = OverTheWire(EncodeKeyframe(kf, 9));
    const auto back = DecodeKeyframe(message);
    ASSERT_TRUE(back.has_value());
    EXPECT_EQ(back->robot, 2);
    EXPECT_EQ(back->index, 17);
    EXPECT_EQ(back->stamp_ns, kf.stamp_ns);
    EXPECT_TRUE(back->T_odom_sensor.isApprox(kf.T_odom_sensor, kPoseTolerance));
    ASSERT_EQ(back->cloud->size(), kf.cloud->size());
    EXPECT_NE(back->cloud.get(), kf.cloud.get());  // another process would get a copy
    for (size_t i = 0; i < kf.cloud->size(); ++i) EXPECT_EQ((*back->cloud)[i], (*kf.cloud)[i]);
}

TEST(Convert, KeyframeCloudIsTheSameObjectInProcess) {
    const auto kf = MakeKeyframe(1000);
    const auto message = EncodeKeyframe(kf, 1);
    EXPECT_EQ(static_cast<const void*>(message.frames.at(0).data()),
              static_cast<const void*>(kf.cloud->data()));
    // Through ZeroMQ frames built over the same bytes (what inproc does), no copy either.
    auto frames = transport::Encode(message);
    auto decoded = transport::Decode(std::move(frames));
    ASSERT_EQ(decoded.status, transport::DecodeResult::Status::kOk);
    const auto back = DecodeKeyframe(*decoded.message);
    ASSERT_TRUE(back.has_value());
    EXPECT_EQ(back->cloud.get(), kf.cloud.get());
}

TEST(Convert, MalformedKeyframesAreRejected) {
    const auto kf = MakeKeyframe(100);
    auto truncated = OverTheWire(EncodeKeyframe(kf, 1));
    truncated.frames[0] = transport::SharedBuffer::Copy(truncated.frames[0].data(), 1199);
    EXPECT_FALSE(DecodeKeyframe(truncated).has_value());

    v1::Keyframe proto;
    ASSERT_TRUE(proto.ParseFromString(EncodeKeyframe(kf, 1).envelope.payload()));
    proto.mutable_t_odom_base()->set_qw(7.0);  // not a unit quaternion
    EXPECT_FALSE(DecodeKeyframe(transport::Pack(proto, {EncodeKeyframe(kf, 1).frames[0]})));

    v1::Keyframe lying;
    ASSERT_TRUE(lying.ParseFromString(EncodeKeyframe(kf, 1).envelope.payload()));
    lying.mutable_cloud()->set_point_count(1ull << 62);  // overflows count * stride
    EXPECT_FALSE(DecodeKeyframe(transport::Pack(lying, {EncodeKeyframe(kf, 1).frames[0]})));

    auto garbage = EncodeKeyframe(kf, 1);
    garbage.envelope.set_payload("\xff\xff\xff garbage");
    EXPECT_FALSE(DecodeKeyframe(garbage).has_value());
    v1::Heartbeat other;
    EXPECT_FALSE(DecodeKeyframe(transport::Pack(other)).has_value());
}

TEST(Convert, ScanContextRoundTripsAndRejectsWrongSizes) {
    const auto kf = MakeKeyframe(20000);
    const auto sc = slam::MakeScanContext(*kf.cloud, slam::ScanContextConfig{});
    std::string bytes;
    ASSERT_TRUE(ToProto(sc, {1, 5}, DescriptorWire::kFloat32).SerializeToString(&bytes));
    v1::ScanContextDescriptor parsed;
    ASSERT_TRUE(parsed.ParseFromString(bytes));
    const auto back = FromProto(parsed);
    ASSERT_TRUE(back.has_value());
    EXPECT_EQ(back->bins, sc.bins);
    EXPECT_EQ(back->ring_key, sc.ring_key);
    EXPECT_TRUE(back->sector_key.isApprox(sc.sector_key, 1e-6f));
    EXPECT_EQ(FromProto(parsed.pose_id())->index, 5);
    EXPECT_NEAR(slam::ScanContextDistance(*back, sc).distance, 0.0, 1e-6);

    parsed.mutable_values()->RemoveLast();
    EXPECT_FALSE(FromProto(parsed).has_value());
    ASSERT_TRUE(parsed.ParseFromString(bytes));
    parsed.set_values(3, std::nanf(""));
    EXPECT_FALSE(FromProto(parsed).has_value());
}

TEST(Convert, CompactScanContextIsSmallCloseAndRejectsForgedBytes) {
    constexpr double kHalfStepM = 0.025 + 1e-6;  // 5 cm height steps
    constexpr double kMaxDistanceChange =
        0.01;  // slam/frontend/scan_context_compression's own bound
    const auto kf = MakeKeyframe(20000);
    const auto sc = slam::MakeScanContext(*kf.cloud, slam::ScanContextConfig{});
    std::string compact_bytes;
    std::string float_bytes;
    ASSERT_TRUE(ToProto(sc, {1, 5}).SerializeToString(&compact_bytes));
    ASSERT_TRUE(ToProto(sc, {1, 5}, DescriptorWire::kFloat32).SerializeToString(&float_bytes));
    // A random synthetic cloud compresses least (real scans: tests/slam/frontend).
    EXPECT_LT(compact_bytes.size() * 2, float_bytes.size());
    v1::ScanContextDescriptor parsed;
    ASSERT_TRUE(parsed.ParseFromString(compact_bytes));
    EXPECT_EQ(parsed.values_size(), 0);
    const auto back = FromProto(parsed);
    ASSERT_TRUE(back.has_value());
    ASSERT_EQ(back->bins.rows(), sc.bins.rows());
    ASSERT_EQ(back->bins.cols(), sc.bins.cols());
    EXPECT_LE((back->bins - sc.bins).cwiseAbs().maxCoeff(), kHalfStepM);
    EXPECT_LT(slam::ScanContextDistance(*back, sc).distance, kMaxDistanceChange);

    v1::ScanContextDescriptor wrong_size = parsed;
    wrong_size.set_num_sectors(parsed.num_sectors() + 1);  // header disagrees with the bytes
    EXPECT_FALSE(FromProto(wrong_size).has_value());
    v1::ScanContextDescriptor truncated = parsed;
    truncated.set_compact(parsed.compact().substr(0, parsed.compact().size() / 2));
    EXPECT_FALSE(FromProto(truncated).has_value());
    v1::ScanContextDescriptor garbage = parsed;
    garbage.set_compact(std::string(64, '\x7f'));
    EXPECT_FALSE(FromProto(garbage).has_value());
}

TEST(Convert, LoopClosureRoundTripsAndRejectsBadWeights) {
    slam::LoopClosure loop;
    loop.a = {0, 12};
    loop.b = {1, 40};
    loop.T_a_b.linear() = Eigen::AngleAxisd(-2.5, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    loop.T_a_b.translation() = Eigen::Vector3d(1, 2, 3);
    loop.kappa = 125000.0;
    loop.tau = 400.0;
    std::string bytes;
    ASSERT_TRUE(ToProto(loop).SerializeToString(&bytes));
    v1::LoopClosure parsed;
    ASSERT_TRUE(parsed.ParseFromString(bytes));
    const auto back = FromProto(parsed);
    ASSERT_TRUE(back.has_value());
    EXPECT_EQ(back->a, loop.a);
    EXPECT_EQ(back->b, loop.b);
    EXPECT_TRUE(back->T_a_b.isApprox(loop.T_a_b, kPoseTolerance));
    EXPECT_EQ(back->kappa, loop.kappa);
    EXPECT_EQ(back->tau, loop.tau);

    parsed.mutable_information()->set_tau(-1.0);
    EXPECT_FALSE(FromProto(parsed).has_value());
    v1::LoopClosure empty;
    EXPECT_FALSE(FromProto(empty).has_value());
}

/// A measured rotation that is not a rotation (merged parallel edges: a weighted mean of two)
/// crosses the wire exactly; a rotation goes as its quaternion alone; malformed matrices are
/// dropped.
TEST(Convert, LoopClosureCarriesAMeasuredRotationThatIsNotOneExactly) {
    slam::LoopClosure loop;
    loop.a = {0, 3};
    loop.b = {2, 7};
    loop.T_a_b.linear() = 0.75 * Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitX()).matrix() +
                          0.25 * Eigen::AngleAxisd(-0.9, Eigen::Vector3d::UnitY()).matrix();
    loop.T_a_b.translation() = Eigen::Vector3d(-1, 0.5, 2);
    const v1::LoopClosure proto = ToProto(loop);
    ASSERT_EQ(proto.rotation_3x3_size(), 9);
    const auto back = FromProto(proto);
    ASSERT_TRUE(back.has_value());
    EXPECT_EQ(back->T_a_b.linear(), loop.T_a_b.linear());
    EXPECT_EQ(back->T_a_b.translation(), loop.T_a_b.translation());

    slam::LoopClosure rigid = loop;
    rigid.T_a_b.linear() = Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitX()).matrix();
    EXPECT_EQ(ToProto(rigid).rotation_3x3_size(), 0);

    v1::LoopClosure short_matrix = proto;
    short_matrix.mutable_rotation_3x3()->RemoveLast();
    EXPECT_FALSE(FromProto(short_matrix).has_value());
    v1::LoopClosure not_finite = proto;
    not_finite.set_rotation_3x3(4, std::nan(""));
    EXPECT_FALSE(FromProto(not_finite).has_value());
    v1::LoopClosure huge = proto;
    huge.set_rotation_3x3(0, 50.0);
    EXPECT_FALSE(FromProto(huge).has_value());
}

TEST(Convert, PublicPosesRoundTripAndRejectCountMismatch) {
    certify::PoseBlocks poses;
    poses.ids = {{0, 3}, {0, 9}};
    poses.blocks = Eigen::MatrixXd::Random(5, 8);
    poses.iteration = 42;
    poses.staircase_level = 1;
    poses.sweep_color = 3;
    std::string bytes;
    ASSERT_TRUE(ToProto(poses).SerializeToString(&bytes));
    v1::PublicPoses parsed;
    ASSERT_TRUE(parsed.ParseFromString(bytes));
    const auto back = FromProto(parsed);
    ASSERT_TRUE(back.has_value());
    EXPECT_EQ(back->ids, poses.ids);
    EXPECT_EQ(back->blocks, poses.blocks);
    EXPECT_EQ(back->iteration, 42u);
    EXPECT_EQ(back->staircase_level, 1);
    EXPECT_EQ(back->sweep_color, 3);

    parsed.set_sweep_color(1u << 31);  // more colours than any team could need
    EXPECT_FALSE(FromProto(parsed).has_value());
    ASSERT_TRUE(parsed.ParseFromString(bytes));
    parsed.mutable_blocks()->RemoveLast();
    EXPECT_FALSE(FromProto(parsed).has_value());
    ASSERT_TRUE(parsed.ParseFromString(bytes));
    parsed.set_rank_r(2);
    EXPECT_FALSE(FromProto(parsed).has_value());
}

TEST(Convert, CertificateReportCarriesVerdictAndLambda) {
    certify::CertificateResult result;
    result.status = certify::CertificateResult::Status::kNotOptimal;
    result.lambda_min = -0.25;
    result.objective = 3.0;
    const auto report = ToProto(result, 5);
    EXPECT_EQ(report.verdict(), v1::CERTIFICATE_VERDICT_NOT_CERTIFIED);
    EXPECT_EQ(report.lambda_min(), -0.25);
    EXPECT_EQ(report.rank_r(), 5u);
    EXPECT_EQ(VerdictOf(certify::CertificateResult::Status::kCertified),
              v1::CERTIFICATE_VERDICT_CERTIFIED);
    EXPECT_FALSE(report.has_bound());
}

TEST(Convert, EveryVerdictKeepsTheCertificatesSpellingOnTheWire) {
    using S = certify::CertificateResult::Status;
    for (const S status : {S::kCertified, S::kNotOptimal, S::kNotCritical, S::kInconclusive}) {
        certify::CertificateResult result;
        result.status = status;
        EXPECT_EQ(VerdictName(ToProto(result, 3).verdict()), certify::VerdictName(status));
    }
    EXPECT_EQ(VerdictName(v1::CERTIFICATE_VERDICT_UNSPECIFIED), "none");
}

TEST(Convert, CertifiedReportCarriesItsProvenBound) {
    certify::CertificateResult result;
    result.status = certify::CertificateResult::Status::kCertified;
    result.has_bound = true;
    result.objective = 10.0;
    result.lower_bound = 9.99999;
    result.relative_suboptimality_bound = 1e-6;
    const auto report = ToProto(result, 3);
    EXPECT_TRUE(report.has_bound());
    EXPECT_EQ(report.lower_bound(), 9.99999);
    EXPECT_EQ(report.relative_suboptimality_bound(), 1e-6);
    EXPECT_EQ(report.objective(), 10.0);
}

}  // namespace
}  // namespace certislam::actors
