// Writes the seed corpus of the message body fuzzer (bodies_fuzz.cpp): one real encoded message
// per body and wire form, as byte 0 = body kind, then its frames (fuzz_frames.h).
// Usage: bodies_fuzz_seeds OUT_DIR
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "actors/convert.h"
#include "slam/frontend/scan_context.h"
#include "tests/fuzz/fuzz_frames.h"
#include "transport/message.h"

namespace certislam::fuzz {
namespace {

// The fuzzer's input for `message`: its kind, its payload as frame 0, its binary frames after.
std::string Input(char kind, const transport::Message& message) {
    std::vector<zmq::message_t> frames;
    frames.emplace_back(message.envelope.payload().data(), message.envelope.payload().size());
    for (const auto& frame : message.frames) frames.emplace_back(frame.data(), frame.size());
    return std::string(1, kind) + JoinFrames(frames);
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

std::vector<std::string> Seeds() {
    const slam::PointCloudPtr cloud = SmallCloud();
    slam::Keyframe keyframe{1, 3, 1'700'000'000'000'000'000, Eigen::Isometry3d::Identity(), cloud};
    keyframe.T_odom_sensor.translation() << 1.0, 2.0, 0.5;
    v1::CloudReply reply;
    *reply.mutable_pose_id() = actors::ToProto(slam::PoseId{1, 3});
    const slam::ScanContext sc = slam::MakeScanContext(*cloud, slam::ScanContextConfig{});
    slam::LoopClosure loop{{0, 2}, {1, 3}, keyframe.T_odom_sensor, 100.0, 10.0, 0.1, 0.01, false};
    certify::PoseBlocks poses;
    poses.ids = {{0, 2}, {1, 3}};
    poses.blocks = Eigen::MatrixXd::Random(5, 8);
    return {Input(0, actors::EncodeKeyframe(keyframe, 7)),
            Input(1, actors::EncodeCloudReply(reply, cloud, actors::CloudWire::kCompact)),
            Input(1, actors::EncodeCloudReply(reply, cloud, actors::CloudWire::kFloat32)),
            Input(2, actors::ToProto(sc, {1, 3}, actors::DescriptorWire::kCompact)),
            Input(2, actors::ToProto(sc, {1, 3}, actors::DescriptorWire::kFloat32)),
            Input(3, actors::ToProto(loop)),
            Input(3, actors::LoopWithdrawal({0, 2}, {1, 3})),
            Input(4, actors::ToProto(poses)),
            Input(5, actors::TrajectoryToProto(
                         1, {keyframe.T_odom_sensor, Eigen::Isometry3d::Identity()}, true, 9))};
}

}  // namespace
}  // namespace certislam::fuzz

int main(int argc, char** argv) {
    if (argc != 2) {
        std::fprintf(stderr, "usage: bodies_fuzz_seeds OUT_DIR\n");
        return 2;
    }
    std::filesystem::create_directories(argv[1]);
    int k = 0;
    for (const std::string& seed : certislam::fuzz::Seeds()) {
        std::ofstream(std::string(argv[1]) + "/seed" + std::to_string(k++), std::ios::binary)
            << seed;
    }
    std::printf("%d seeds in %s\n", k, argv[1]);
    return 0;
}
