// The MapUpdate decoder: a zstd payload decompresses to the submap bytes, a move-only update has
// none, and a lying size, a foreign anchor or an unknown compression decode to nothing.
#include <gtest/gtest.h>
#include <zstd.h>

#include "actors/convert.h"

namespace certislam::actors {
namespace {

transport::Message MapMessage(const std::string& payload, std::uint64_t claimed) {
    std::string packed(ZSTD_compressBound(payload.size()), '\0');
    packed.resize(ZSTD_compress(packed.data(), packed.size(), payload.data(), payload.size(), 1));
    v1::MapUpdate update;
    *update.mutable_header() = MakeHeader(3, 1, 0);
    update.set_submap_id(4);
    *update.mutable_anchor_pose_id() = ToProto(slam::PoseId{3, 8});
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() << 1.0, 2.0, 3.0;
    *update.mutable_t_world_anchor() = ToProto(T);
    update.set_kind(v1::MAP_PAYLOAD_KIND_TSDF_BLOCKS);
    update.set_compression(v1::MAP_COMPRESSION_ZSTD);
    update.set_byte_length(packed.size());
    update.set_uncompressed_byte_length(claimed);
    return transport::Pack(update, {transport::SharedBuffer::Copy(packed.data(), packed.size())});
}

TEST(ConvertMap, ZstdPayloadDecodesToTheSubmapBytes) {
    const std::string payload(10000, 's');
    const auto body = DecodeMapUpdate(MapMessage(payload, payload.size()));
    ASSERT_TRUE(body.has_value());
    EXPECT_EQ(body->sender, 3);
    EXPECT_EQ(body->submap, 4);
    EXPECT_EQ(body->anchor, (slam::PoseId{3, 8}));
    EXPECT_NEAR(body->T_world_anchor.translation().z(), 3.0, 1e-12);
    ASSERT_TRUE(body->bytes.has_value());
    EXPECT_EQ(*body->bytes, payload);
}

TEST(ConvertMap, MoveOnlyUpdateCarriesNoBytes) {
    auto message = MapMessage("x", 1);
    auto update = *transport::Unpack<v1::MapUpdate>(message);
    update.set_byte_length(0);
    const auto body = DecodeMapUpdate(transport::Pack(update));
    ASSERT_TRUE(body.has_value());
    EXPECT_FALSE(body->bytes.has_value());
}

TEST(ConvertMap, LyingOrForeignUpdatesDecodeToNothing) {
    const std::string payload(1000, 'p');
    EXPECT_FALSE(DecodeMapUpdate(MapMessage(payload, payload.size() + 1)));
    EXPECT_FALSE(DecodeMapUpdate(MapMessage(payload, kMaxSubmapBytes + 1)));
    auto foreign = *transport::Unpack<v1::MapUpdate>(MapMessage(payload, payload.size()));
    *foreign.mutable_anchor_pose_id() = ToProto(slam::PoseId{1, 8});
    EXPECT_FALSE(DecodeMapUpdate(transport::Pack(foreign)));
    auto zlib = *transport::Unpack<v1::MapUpdate>(MapMessage(payload, payload.size()));
    zlib.set_compression(v1::MAP_COMPRESSION_ZLIB);
    const auto message = MapMessage(payload, payload.size());
    EXPECT_FALSE(DecodeMapUpdate(transport::Pack(zlib, {message.frames[0]})));
}

}  // namespace
}  // namespace certislam::actors
