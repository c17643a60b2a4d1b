// Envelope packing and strict decoding: versions, unknown fields, truncation, frame tables.
#include "transport/message.h"

#include <gtest/gtest.h>

#include <random>

#include "certislam/v1/keyframe.pb.h"
#include "certislam/v1/scan_context.pb.h"

namespace certislam::transport {
namespace {

using Status = DecodeResult::Status;

v1::Keyframe MakeKeyframe(std::uint64_t cloud_bytes) {
    v1::Keyframe keyframe;
    keyframe.mutable_header()->set_robot_id(2);
    keyframe.mutable_header()->set_sequence(17);
    keyframe.mutable_header()->set_stamp_ns(1'700'000'000'123'456'789);
    keyframe.mutable_pose_id()->set_robot_id(2);
    keyframe.mutable_pose_id()->set_index(5);
    keyframe.mutable_t_odom_base()->set_qw(1.0);
    keyframe.mutable_t_odom_base()->set_tx_m(3.5);
    keyframe.mutable_cloud()->set_frame_index(0);
    keyframe.mutable_cloud()->set_point_count(cloud_bytes / 16);
    keyframe.mutable_cloud()->set_point_stride_bytes(16);
    keyframe.mutable_cloud()->set_format(v1::POINT_FORMAT_XYZI_F32);
    keyframe.mutable_cloud()->set_byte_length(cloud_bytes);
    return keyframe;
}

std::vector<zmq::message_t> Copy(const std::vector<zmq::message_t>& frames) {
    std::vector<zmq::message_t> copy;
    for (const auto& frame : frames) copy.emplace_back(frame.data(), frame.size());
    return copy;
}

TEST(Message, PackDecodeUnpackRoundTripsPayloadHeaderAndFrames) {
    const auto cloud = SharedBuffer::Copy(std::string(1600, 'x').data(), 1600);
    const Message sent = Pack(MakeKeyframe(1600), {cloud});
    EXPECT_EQ(sent.type_name(), "certislam.v1.Keyframe");
    EXPECT_EQ(sent.envelope.header().sequence(), 17u);

    DecodeResult result = Decode(Encode(sent));
    ASSERT_EQ(result.status, Status::kOk) << result.detail;
    const Message& got = *result.message;
    ASSERT_EQ(got.frames.size(), 1u);
    EXPECT_EQ(got.frames[0].size(), 1600u);
    EXPECT_EQ(std::memcmp(got.frames[0].data(), cloud.data(), 1600), 0);
    EXPECT_FALSE(Unpack<v1::ScanContextDescriptor>(got).has_value());
    const auto keyframe = Unpack<v1::Keyframe>(got);
    ASSERT_TRUE(keyframe.has_value());
    EXPECT_EQ(keyframe->pose_id().index(), 5u);
    EXPECT_DOUBLE_EQ(keyframe->t_odom_base().tx_m(), 3.5);
    EXPECT_EQ(got.envelope.header().robot_id(), 2u);
}

TEST(Message, RejectsUnknownMajorVersionButAcceptsNewerMinor) {
    Message message = Pack(MakeKeyframe(0));
    message.envelope.set_schema_major(kSchemaMajor + 1);
    EXPECT_EQ(Decode(Encode(message)).status, Status::kUnsupportedVersion);

    message.envelope.set_schema_major(kSchemaMajor);
    message.envelope.set_schema_minor(kSchemaMinor + 7);
    EXPECT_EQ(Decode(Encode(message)).status, Status::kOk);
}

TEST(Message, IgnoresUnknownFieldsInEnvelopeAndPayload) {
    Message message = Pack(MakeKeyframe(0));
    // Field 99, varint 42: a field a later minor version might add.
    const std::string unknown_field = {static_cast<char>(((99 << 3) & 0x7f) | 0x80),
                                       static_cast<char>(99 >> 4), 42};
    message.envelope.mutable_payload()->append(unknown_field);
    auto frames = Encode(message);
    std::string envelope_bytes = frames[0].to_string() + unknown_field;
    frames[0] = zmq::message_t(envelope_bytes.data(), envelope_bytes.size());

    DecodeResult result = Decode(std::move(frames));
    ASSERT_EQ(result.status, Status::kOk) << result.detail;
    const auto keyframe = Unpack<v1::Keyframe>(*result.message);
    ASSERT_TRUE(keyframe.has_value());
    EXPECT_EQ(keyframe->header().sequence(), 17u);
}

TEST(Message, RejectsWrongFrameCountAndWrongFrameSize) {
    const auto cloud = SharedBuffer::Copy(std::string(64, 'y').data(), 64);
    const Message message = Pack(MakeKeyframe(64), {cloud});

    auto missing = Encode(message);
    missing.pop_back();
    EXPECT_EQ(Decode(std::move(missing)).status, Status::kFrameCountMismatch);

    auto extra = Encode(message);
    extra.emplace_back(8);
    EXPECT_EQ(Decode(std::move(extra)).status, Status::kFrameCountMismatch);

    auto short_frame = Encode(message);
    short_frame[1] = zmq::message_t(32);
    EXPECT_EQ(Decode(std::move(short_frame)).status, Status::kFrameSizeMismatch);

    EXPECT_EQ(Decode({}).status, Status::kEmpty);
}

TEST(Message, EveryTruncationOfAnEnvelopeIsAnErrorOrAValidPrefixNeverACrash) {
    Message message = Pack(MakeKeyframe(0));
    const std::string bytes = Encode(message)[0].to_string();
    int rejected = 0;
    for (std::size_t length = 0; length < bytes.size(); ++length) {
        std::vector<zmq::message_t> frames;
        frames.emplace_back(bytes.data(), length);
        const DecodeResult result = Decode(std::move(frames));
        if (result.status != Status::kOk) ++rejected;
    }
    // A prefix that ends on a field boundary can still parse (protobuf has no length header),
    // but most cuts must be rejected, and none may crash.
    EXPECT_GT(rejected, static_cast<int>(bytes.size()) / 2);
}

TEST(Message, RandomGarbageIsRejected) {
    std::mt19937 rng(7);
    std::uniform_int_distribution<int> byte(0, 255);
    int accepted = 0;
    constexpr int kTrials = 2000;
    for (int trial = 0; trial < kTrials; ++trial) {
        std::string garbage(1 + trial % 200, '\0');
        for (auto& c : garbage) c = static_cast<char>(byte(rng));
        std::vector<zmq::message_t> frames;
        frames.emplace_back(garbage.data(), garbage.size());
        if (trial % 3 == 0) frames.emplace_back(Copy(frames)[0].size());
        if (Decode(std::move(frames)).status == Status::kOk) ++accepted;
    }
    EXPECT_EQ(accepted, 0);
}

TEST(Message, EnforcesLimits) {
    DecodeLimits limits;
    limits.max_frames = 1;
    const auto a = SharedBuffer::Copy("ab", 2);
    const Message message = Pack(MakeKeyframe(0), {a, a});
    EXPECT_EQ(Decode(Encode(message), limits).status, Status::kTooLarge);
    limits.max_frames = 4;
    limits.max_frame_bytes = 1;
    EXPECT_EQ(Decode(Encode(message), limits).status, Status::kTooLarge);
    limits.max_frame_bytes = 0;
    EXPECT_THROW(limits.Validate(), std::invalid_argument);
}

}  // namespace
}  // namespace certislam::transport
