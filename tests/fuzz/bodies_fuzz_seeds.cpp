// Writes the seed corpus of the message body fuzzer (bodies_fuzz.cpp): one real encoded message
// per body and wire form, as byte 0 = body kind, then its frames (fuzz_frames.h).
// With LOG_DIR, also the durable log fuzzer's seeds: real logs (a header alone, and a header with a
// keyframe and a loop closure appended).
// Usage: bodies_fuzz_seeds OUT_DIR [LOG_DIR]
#include <zstd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "actors/convert.h"
#include "actors/convert_descriptor.h"
#include "actors/durable_log.h"
#include "certislam/v1/control.pb.h"
#include "slam/frontend/scan_context.h"
#include "tests/fuzz/fuzz_frames.h"
#include "transport/message.h"

namespace certislam::fuzz {
namespace {

// The fuzzer's input for `message`: its kind (bodies_fuzz.cpp's kBodies), then its frames.
std::string Input(char kind, const transport::Message& message) {
    return std::string(1, kind) + JoinFrames(BodyFrames(message));
}

template <class T>
std::string Input(char kind, const T& proto) {
    return Input(kind, transport::Pack(proto));
}

slam::PointCloudPtr SmallCloud() {
    auto cloud = std::make_shared<slam::PointCloud>();
    for (int i = 0; i < 64; ++i) {
        const float a = 0.1f * static_cast<float>(i);
        cloud->emplace_back(10.0f * std::cos(a), 10.0f * std::sin(a),
                            0.05f * static_cast<float>(i));
    }
    return cloud;
}

// A map update whose frame is `payload` compressed with zstd.
transport::Message MapSeed(const std::string& payload) {
    std::string packed(ZSTD_compressBound(payload.size()), '\0');
    packed.resize(ZSTD_compress(packed.data(), packed.size(), payload.data(), payload.size(), 3));
    v1::MapUpdate update;
    *update.mutable_header() = actors::MakeHeader(1, 4, 0);
    update.set_submap_id(2);
    *update.mutable_anchor_pose_id() = actors::ToProto(slam::PoseId{1, 3});
    *update.mutable_t_world_anchor() = actors::ToProto(Eigen::Isometry3d::Identity());
    update.set_kind(v1::MAP_PAYLOAD_KIND_TSDF_BLOCKS);
    update.set_compression(v1::MAP_COMPRESSION_ZSTD);
    update.set_byte_length(packed.size());
    update.set_uncompressed_byte_length(payload.size());
    return transport::Pack(update, {transport::SharedBuffer::Copy(packed.data(), packed.size())});
}

// The distributed certificate round's messages and the solver's status and report.
std::vector<std::string> CertifierSeeds() {
    v1::SolverStatus status;
    *status.mutable_header() = actors::MakeHeader(1, 5, 0);
    status.set_rank_r(5);
    status.set_cost(12.5);
    status.set_gradient_norm(1e-3);
    status.set_team_round(3);
    v1::CertificateRound round;
    round.set_round(1'700'000'000'000'001);
    round.set_rank_r(5);
    for (std::uint32_t r : {0u, 1u}) {
        auto* ref = round.add_bundles();
        ref->set_robot_id(r);
        ref->set_digest(0x1234567890abcdefull + r);
        ref->add_neighbors(1 - r);
    }
    v1::CertificateVector vector;
    *vector.mutable_header() = actors::MakeHeader(1, 6, 0);
    vector.set_round(round.round());
    vector.set_step(2);
    vector.set_block_size(actors::kCertificateBlock);
    for (int i = 0; i < 2; ++i) *vector.add_pose_ids() = actors::ToProto(slam::PoseId{1, i});
    for (int i = 0; i < 8; ++i) vector.add_values(0.125 * i - 0.5);
    v1::CertificateReduction reduction;
    *reduction.mutable_header() = actors::MakeHeader(1, 7, 0);
    reduction.set_round(round.round());
    reduction.set_step(2);
    reduction.set_stage(1);
    for (double v : {1.5, -2.0, 3e-9}) reduction.add_values(v);
    v1::CertificateReport report;
    report.set_verdict(v1::CERTIFICATE_VERDICT_CERTIFIED);
    report.set_lambda_min(-1e-9);
    report.set_reason("seed");
    return {Input(7, status),
            Input(8, round),
            Input(9, vector),
            Input(10, reduction),
            Input(11, MapSeed(std::string(4096, 'm'))),
            Input(12, report),
            Input(13, v1::Shutdown{})};
}

std::vector<std::string> Seeds() {
    const slam::PointCloudPtr cloud = SmallCloud();
    slam::Keyframe keyframe{1, 3, 1'700'000'000'000'000'000, Eigen::Isometry3d::Identity(), cloud};
    keyframe.T_odom_sensor.translation() << 1.0, 2.0, 0.5;
    v1::CloudReply reply;
    *reply.mutable_pose_id() = actors::ToProto(slam::PoseId{1, 3});
    v1::CloudRequest request;
    *request.mutable_pose_id() = actors::ToProto(slam::PoseId{1, 3});
    const slam::ScanContext sc = slam::MakeScanContext(*cloud, slam::ScanContextConfig{});
    slam::LoopClosure loop{{0, 2}, {1, 3}, keyframe.T_odom_sensor, 100.0, 10.0, 0.1, 0.01, false};
    certify::PoseBlocks poses;
    poses.ids = {{0, 2}, {1, 3}};
    poses.blocks = Eigen::MatrixXd::Random(5, 8);
    std::vector<std::string> seeds = {
        Input(0, actors::EncodeKeyframe(keyframe, 7)),
        Input(1, actors::EncodeCloudReply(reply, cloud, actors::CloudWire::kCompact)),
        Input(1, actors::EncodeCloudReply(reply, cloud, actors::CloudWire::kFloat32)),
        Input(2, actors::ToProto(sc, {1, 3}, actors::DescriptorWire::kCompact)),
        Input(2, actors::ToProto(sc, {1, 3}, actors::DescriptorWire::kFloat32)),
        Input(3, actors::ToProto(loop)),
        Input(3, actors::LoopWithdrawal({0, 2}, {1, 3})),
        Input(4, actors::ToProto(poses)),
        Input(5, actors::TrajectoryToProto(
                     1, {keyframe.T_odom_sensor, Eigen::Isometry3d::Identity()}, true, 9)),
        Input(6, request)};
    for (auto& seed : CertifierSeeds()) seeds.push_back(std::move(seed));
    return seeds;
}

// Real durable logs of one robot's mission in `dir`.
void WriteLogSeeds(const std::string& dir) {
    std::filesystem::create_directories(dir);
    const std::string identity = "config_digest: 3f2a\nsource: sim seed 7\nrobot: 1\n";
    { actors::DurableLog header_only(dir + "/header-only", identity); }
    actors::DurableLog log(dir + "/keyframe-loop", identity);
    slam::Keyframe keyframe{1, 3, 1'700'000'000'000'000'000, Eigen::Isometry3d::Identity(),
                            SmallCloud()};
    log.Append(actors::EncodeKeyframe(keyframe, 7));
    log.Append(transport::Pack(actors::ToProto(slam::LoopClosure{
        {0, 2}, {1, 3}, Eigen::Isometry3d::Identity(), 100.0, 10.0, 0.1, 0.01, false})));
}

}  // namespace
}  // namespace certislam::fuzz

int main(int argc, char** argv) {
    if (argc != 2 && argc != 3) {
        std::fprintf(stderr, "usage: bodies_fuzz_seeds OUT_DIR [LOG_DIR]\n");
        return 2;
    }
    std::filesystem::create_directories(argv[1]);
    int k = 0;
    for (const std::string& seed : certislam::fuzz::Seeds()) {
        std::ofstream(std::string(argv[1]) + "/seed" + std::to_string(k++), std::ios::binary)
            << seed;
    }
    std::printf("%d seeds in %s\n", k, argv[1]);
    if (argc == 3) certislam::fuzz::WriteLogSeeds(argv[2]);
    return 0;
}
