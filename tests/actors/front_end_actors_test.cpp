// Ingest, descriptor and loop matcher actors of two robots over real inproc sockets on a
// simulated mission: the loops they publish agree with ground truth, each robot's matcher says
// end of loops, clouds cross robots only for candidates, malformed keyframes are counted.
#include <gtest/gtest.h>

#include <thread>

#include "actors/codec.h"
#include "actors/descriptor_actor.h"
#include "actors/ingest_actor.h"
#include "actors/loop_matcher_actor.h"
#include "certislam/v1/control.pb.h"
#include "slam/simulator.h"

namespace certislam::actors {
namespace {

constexpr int kKeyframes = 45;
constexpr double kLoopTranslationTolerance_m = 0.3;
constexpr double kLoopRotationTolerance_rad = 0.035;  // 2 degrees
constexpr auto kTimeout = std::chrono::seconds(60);

TEST(FrontEndActors, TwoRobotsFindTrueInterRobotLoopsAndRequestOnlyCandidateClouds) {
    slam::SimulatorConfig sim;
    sim.seed = 1;
    const slam::MissionGenerator generator(sim);
    zmq::context_t context;
    const std::vector<int> robots{0, 1};
    std::vector<std::unique_ptr<NodeActor>> actors;
    std::vector<LoopMatcherActor*> matchers;
    std::vector<IngestActor*> ingests;
    for (int r : robots) {
        const TeamWiring w = InprocWiring(r, robots);
        auto matcher = std::make_unique<LoopMatcherActor>(context, w, LoopMatcherConfig{});
        matchers.push_back(matcher.get());
        actors.push_back(std::move(matcher));
        actors.push_back(std::make_unique<DescriptorActor>(context, w, slam::ScanContextConfig{}));
        auto next = std::make_shared<int>(0);
        IngestConfig ingest;
        ingest.local_subscribers = 2;
        auto source = [&generator, r, next]() -> std::optional<slam::Keyframe> {
            if (*next >= kKeyframes) return std::nullopt;
            return generator.Generate(r, (*next)++).keyframe;
        };
        auto actor = std::make_unique<IngestActor>(context, w, source, ingest);
        ingests.push_back(actor.get());
        actors.push_back(std::move(actor));
    }
    // The test listens where solvers would: both robots' loop streams.
    std::vector<std::unique_ptr<transport::Endpoint>> listeners;
    for (int r : robots) {
        listeners.push_back(std::make_unique<transport::Endpoint>(
            context, ClientConfig(InprocWiring(0, robots), Edge::kLoops, r)));
    }
    for (auto& a : actors) a->Start();

    std::vector<slam::LoopClosure> loops;
    std::set<int> ended;
    const auto deadline = std::chrono::steady_clock::now() + kTimeout;
    while (ended.size() < 2 && std::chrono::steady_clock::now() < deadline) {
        for (auto& l : listeners) {
            while (auto m = l->Receive(std::chrono::milliseconds(10))) {
                if (auto loop = transport::Unpack<v1::LoopClosure>(*m)) {
                    // A withdrawal (PCM changed its mind) is not a loop: FromProto refuses it.
                    if (auto closure = FromProto(*loop)) loops.push_back(*closure);
                } else if (auto end = transport::Unpack<v1::Shutdown>(*m)) {
                    if (end->reason() == kEndOfLoops) ended.insert(end->header().robot_id());
                }
            }
        }
    }
    ASSERT_EQ(ended.size(), 2u) << "a matcher never said end of loops";
    int inter = 0;
    for (const auto& loop : loops) {
        const Eigen::Isometry3d T_true =
            generator.T_world_sensor_truth(loop.a.robot, loop.a.index).inverse() *
            generator.T_world_sensor_truth(loop.b.robot, loop.b.index);
        const Eigen::Isometry3d error = T_true.inverse() * loop.T_a_b;
        EXPECT_LT(error.translation().norm(), kLoopTranslationTolerance_m);
        EXPECT_LT(Eigen::AngleAxisd(error.linear()).angle(), kLoopRotationTolerance_rad);
        EXPECT_LE(loop.a.robot, loop.b.robot);  // the higher robot checks, the lower is the tail
        inter += loop.inter_robot() ? 1 : 0;
    }
    EXPECT_GE(inter, 1);
    // Robot 0 served clouds only for robot 1's candidates: far less than all its clouds.
    std::uint64_t all_clouds = 0;
    for (int i = 0; i < kKeyframes; ++i) {
        all_clouds += generator.Generate(0, i).keyframe.cloud->size() * 12;
    }
    EXPECT_GT(matchers[0]->BytesSentToPeers(), 0u);
    EXPECT_LT(matchers[0]->BytesSentToPeers(), all_clouds / 2);
    for (auto* ingest : ingests) EXPECT_EQ(ingest->Published(), kKeyframes);
    for (auto& a : actors) EXPECT_EQ(a->Counters().dropped_malformed, 0u) << a->Name();
    for (auto& a : actors) a->Stop();
}

TEST(FrontEndActors, MalformedKeyframeIsDroppedAndCounted) {
    zmq::context_t context;
    const std::vector<int> robots{0};
    const TeamWiring w = InprocWiring(0, robots);
    DescriptorActor descriptor(context, w, slam::ScanContextConfig{});
    transport::Endpoint keyframes(context, ServerConfig(w, Edge::kKeyframes));
    transport::Endpoint listener(context, ClientConfig(w, Edge::kDescriptors, 0));
    descriptor.Start();
    ASSERT_TRUE(keyframes.WaitForSubscribers(1, std::chrono::seconds(5)));
    ASSERT_TRUE(listener.WaitReady(std::chrono::seconds(5)));
    slam::Keyframe kf;
    kf.cloud = std::make_shared<slam::PointCloud>(1000, Eigen::Vector3f(5, 1, 0.5f));
    const auto good_message = EncodeKeyframe(kf, 1);
    v1::Keyframe lying;  // a valid envelope whose cloud reference does not fit its frame
    ASSERT_TRUE(lying.ParseFromString(good_message.envelope.payload()));
    lying.mutable_cloud()->set_point_count(999);
    keyframes.Send(transport::Pack(lying, {good_message.frames[0]}));
    keyframes.Send(EncodeKeyframe(kf, 2));
    const auto good = listener.Receive(std::chrono::seconds(5));
    ASSERT_TRUE(good.has_value());
    EXPECT_TRUE(good->Is<v1::ScanContextDescriptor>());
    descriptor.Stop();  // joins: the counters are final
    EXPECT_EQ(descriptor.Counters().dropped_malformed, 1u);
    EXPECT_GE(descriptor.Counters().handled, 1u);
}

}  // namespace
}  // namespace certislam::actors
