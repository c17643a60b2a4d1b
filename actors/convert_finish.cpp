// The team's second-order finish on the wire (actors/convert.h): one robot's exchanges and sums
// (certify/pipeline/team_finish.h), checked for shape before its TeamFinish sees them.
#include <climits>

#include "actors/convert.h"

namespace certislam::actors {
namespace {

constexpr std::uint32_t kMaxRank = 64;  ///< the largest relaxation rank a block may have
constexpr std::size_t kBlock = 4;       ///< values per pose and row: [Y_i | p_i], d = 3

bool FitsInt(std::uint64_t v) { return v <= static_cast<std::uint64_t>(INT_MAX); }

bool Ids(const google::protobuf::RepeatedPtrField<v1::PoseId>& in, std::vector<slam::PoseId>* out) {
    for (const auto& id : in) {
        const auto pose = FromProto(id);
        if (!pose) return false;
        out->push_back(*pose);
    }
    return true;
}

void PutIds(const std::vector<slam::PoseId>& ids, v1::FinishMessage* out) {
    for (const auto& id : ids) *out->add_pose_ids() = ToProto(id);
}

}  // namespace

std::optional<FinishBody> FromProto(const v1::FinishMessage& message) {
    FinishBody out;
    out.kind = message.kind();
    if (!FitsInt(message.header().robot_id()) || !FitsInt(message.to_robot()) ||
        !FitsInt(message.staircase_level()) || !Ids(message.pose_ids(), &out.ids)) {
        return std::nullopt;
    }
    out.robot = static_cast<int>(message.header().robot_id());
    out.to = static_cast<int>(message.to_robot());
    out.step = message.step();
    out.staircase_level = static_cast<int>(message.staircase_level());
    const auto values = static_cast<std::size_t>(message.values_size());
    switch (message.kind()) {
        case v1::FinishMessage::KIND_EDGES:
            for (const auto& e : message.edges()) {
                auto edge = FromProto(e);
                if (!edge) return std::nullopt;
                out.edges.push_back(std::move(*edge));
            }
            return out;
        case v1::FinishMessage::KIND_VECTOR: {
            const std::uint32_t r = message.rank_r();
            if (r < 1 || r > kMaxRank || values != r * kBlock * out.ids.size()) return std::nullopt;
            out.blocks = Eigen::Map<const Eigen::MatrixXd>(
                message.values().data(), r, static_cast<Eigen::Index>(kBlock * out.ids.size()));
            return out;
        }
        case v1::FinishMessage::KIND_SUMS:
            out.values.assign(message.values().begin(), message.values().end());
            return out;
        default:
            return std::nullopt;
    }
}

v1::FinishMessage ToProto(const certify::FinishEdges& edges) {
    v1::FinishMessage out;
    out.set_kind(v1::FinishMessage::KIND_EDGES);
    out.set_to_robot(static_cast<std::uint32_t>(edges.to));
    PutIds(edges.poses, &out);
    for (const auto& e : edges.edges) *out.add_edges() = ToProto(e);
    return out;
}

v1::FinishMessage ToProto(const certify::FinishVector& vector) {
    v1::FinishMessage out;
    out.set_kind(v1::FinishMessage::KIND_VECTOR);
    out.set_to_robot(static_cast<std::uint32_t>(vector.to));
    out.set_step(vector.step);
    out.set_rank_r(static_cast<std::uint32_t>(vector.blocks.rows()));
    PutIds(vector.ids, &out);
    out.mutable_values()->Add(vector.blocks.data(), vector.blocks.data() + vector.blocks.size());
    return out;
}

v1::FinishMessage ToProto(const certify::FinishSums& sums) {
    v1::FinishMessage out;
    out.set_kind(v1::FinishMessage::KIND_SUMS);
    out.set_step(sums.step);
    out.mutable_values()->Add(sums.values.begin(), sums.values.end());
    return out;
}

}  // namespace certislam::actors
