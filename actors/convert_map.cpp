// The decoder of a peer's MapUpdate (actors/convert.h): header fields and the payload frame,
// decompressed within its declared size, before the mapper deserialises the submap.
#include <zstd.h>

#include <climits>
#include <string_view>

#include "actors/convert.h"

namespace certislam::actors {
namespace {

/// The payload of a MapUpdate's frame; nullopt when the compression is unknown or the frame lies.
std::optional<std::string> Payload(const v1::MapUpdate& update, std::string_view frame) {
    if (update.compression() == v1::MAP_COMPRESSION_NONE) return std::string(frame);
    if (update.compression() != v1::MAP_COMPRESSION_ZSTD) return std::nullopt;
    const std::uint64_t size = update.uncompressed_byte_length();
    if (size > kMaxSubmapBytes || ZSTD_getFrameContentSize(frame.data(), frame.size()) != size) {
        return std::nullopt;
    }
    std::string out(size, '\0');
    const std::size_t n = ZSTD_decompress(out.data(), out.size(), frame.data(), frame.size());
    if (ZSTD_isError(n) || n != size) return std::nullopt;
    return out;
}

}  // namespace

std::optional<MapBody> DecodeMapUpdate(const transport::Message& message) {
    const auto proto = transport::Unpack<v1::MapUpdate>(message);
    if (!proto || proto->header().robot_id() > static_cast<std::uint32_t>(INT_MAX) ||
        proto->submap_id() > static_cast<std::uint64_t>(INT_MAX)) {
        return std::nullopt;
    }
    MapBody body;
    body.sender = static_cast<int>(proto->header().robot_id());
    body.submap = static_cast<int>(proto->submap_id());
    const auto anchor = FromProto(proto->anchor_pose_id());
    const auto T = FromProto(proto->t_world_anchor());
    if (!anchor || !T || anchor->robot != body.sender) return std::nullopt;
    body.anchor = *anchor;
    body.T_world_anchor = *T;
    if (proto->byte_length() == 0) return body;  // moved only
    const auto index = static_cast<std::size_t>(proto->frame_index());
    if (proto->kind() != v1::MAP_PAYLOAD_KIND_TSDF_BLOCKS || index >= message.frames.size() ||
        message.frames[index].size() != proto->byte_length()) {
        return std::nullopt;
    }
    const auto& frame = message.frames[index];
    body.bytes = Payload(
        *proto, std::string_view(reinterpret_cast<const char*>(frame.data()), frame.size()));
    if (!body.bytes) return std::nullopt;
    return body;
}

}  // namespace certislam::actors
