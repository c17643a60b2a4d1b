// Ingest, descriptor and loop matcher actors of two robots over real inproc sockets on a
// simulated mission: the loops they publish agree with ground truth, each robot's matcher says
// end of loops, clouds cross robots only for candidates (through the cloud-request gate, each
// downsampled at the registration voxel; at most the best candidates per keyframe when capped),
// malformed keyframes are counted, and an end-of-descriptors marker that overtakes the
// descriptors (a late subscriber) does not end the matcher.
#include <gtest/gtest.h>

#include <map>
#include <thread>

#include "actors/convert.h"
#include "actors/convert_descriptor.h"
#include "actors/descriptor_actor.h"
#include "actors/ingest_actor.h"
#include "actors/loop_matcher_actor.h"
#include "certislam/v1/control.pb.h"
#include "slam/frontend/downsample.h"
#include "slam/sim/simulator.h"

namespace certislam::actors {
namespace {

constexpr int kKeyframes = 45;
constexpr double kLoopTranslationTolerance_m = 0.3;
constexpr double kLoopRotationTolerance_rad = 0.035;  // 2 degrees
constexpr auto kTimeout = std::chrono::seconds(60);

/// What a two-robot front end run sent.
struct FrontEndRun {
    std::vector<slam::LoopClosure> loops;  ///< every loop on both loop streams
    int inter = 0;                         ///< inter-robot loops among them
    int clouds_requested = 0;              ///< robot 1's cloud requests (distinct)
    int skipped = 0;                       ///< robot 1's candidates the gate skipped
    int capped = 0;                        ///< robot 1's candidates the per-query cap left out
    int registered = 0;                    ///< robot 1's registrations (verified + rejected)
    int verified = 0;                      ///< robot 1's verified registrations
    /// The loops accepted at the end: every loop sent, less those withdrawn after.
    std::map<std::pair<slam::PoseId, slam::PoseId>, slam::LoopClosure> accepted;
};

/// Reads both robots' loop streams until each matcher said end of loops (or kTimeout): every
/// loop into run->loops, the accepted ones (withdrawals applied) into run->accepted.
std::set<int> Listen(const std::vector<std::unique_ptr<transport::Endpoint>>& listeners,
                     FrontEndRun* run) {
    std::set<int> ended;
    const auto deadline = std::chrono::steady_clock::now() + kTimeout;
    while (ended.size() < listeners.size() && std::chrono::steady_clock::now() < deadline) {
        for (const auto& l : listeners) {
            while (auto m = l->Receive(std::chrono::milliseconds(10))) {
                if (auto loop = transport::Unpack<v1::LoopClosure>(*m)) {
                    // A withdrawal (PCM changed its mind) is not a loop: FromProto refuses it.
                    if (auto closure = FromProto(*loop)) {
                        run->loops.push_back(*closure);
                        run->accepted[{closure->a, closure->b}] = *closure;
                    } else if (auto ends = WithdrawnEnds(*loop)) {
                        run->accepted.erase(*ends);
                    }
                } else if (auto end = transport::Unpack<v1::Shutdown>(*m)) {
                    if (end->reason() == kEndOfLoops) ended.insert(end->header().robot_id());
                }
            }
        }
    }
    return ended;
}

/// Runs ingest, descriptor and matcher actors of robots 0 and 1 on the simulated mission and
/// checks what every run must show (true loops, end markers, candidate clouds only).
FrontEndRun RunFrontEnd(const LoopMatcherConfig& matcher_config) {
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
        auto matcher = std::make_unique<LoopMatcherActor>(context, w, matcher_config);
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
    listeners.reserve(robots.size());
    for (int r : robots) {
        listeners.push_back(std::make_unique<transport::Endpoint>(
            context, ClientConfig(InprocWiring(0, robots), Edge::kLoops, r)));
    }
    for (auto& a : actors) a->Start();

    FrontEndRun run;
    const std::set<int> ended = Listen(listeners, &run);
    EXPECT_EQ(ended.size(), 2u) << "a matcher never said end of loops";
    int inter = 0;
    for (const auto& loop : run.loops) {
        const Eigen::Isometry3d T_true =
            generator.T_world_sensor_truth(loop.a.robot, loop.a.index).inverse() *
            generator.T_world_sensor_truth(loop.b.robot, loop.b.index);
        const Eigen::Isometry3d error = T_true.inverse() * loop.T_a_b;
        EXPECT_LT(error.translation().norm(), kLoopTranslationTolerance_m);
        EXPECT_LT(Eigen::AngleAxisd(error.linear()).angle(), kLoopRotationTolerance_rad);
        EXPECT_LE(loop.a.robot, loop.b.robot);  // the higher robot checks, the lower is the tail
        inter += loop.inter_robot() ? 1 : 0;
    }
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
    run.inter = inter;
    run.clouds_requested = matchers[1]->CloudsRequested();
    run.skipped = matchers[1]->Skipped();
    run.capped = matchers[1]->Capped();
    run.registered = matchers[1]->Verified() + matchers[1]->Rejected();
    run.verified = matchers[1]->Verified();
    return run;
}

TEST(FrontEndActors, TwoRobotsFindTrueInterRobotLoopsAndRequestOnlyCandidateClouds) {
    const FrontEndRun run = RunFrontEnd(LoopMatcherConfig{});  // place_window 0: no skips
    EXPECT_GE(run.inter, 1);
    EXPECT_EQ(run.skipped, 0);
    EXPECT_EQ(run.capped, 0);
    EXPECT_GE(run.clouds_requested, run.inter);  // at most one cloud per verified candidate
}

// One candidate per own keyframe and robot: robot 1 registers at most one per keyframe against
// robot 0 and one against its own past, leaves the rest out, and still finds true loops.
TEST(FrontEndActors, CandidateCapRegistersTheBestCandidatePerKeyframeAndRobot) {
    LoopMatcherConfig config;
    config.query_stride = 1;  // every keyframe queries: a place matches several keyframes
    const FrontEndRun all = RunFrontEnd(config);
    config.max_candidates_per_query = 1;
    const FrontEndRun run = RunFrontEnd(config);
    EXPECT_GT(run.capped, 0);
    EXPECT_LE(run.registered, 2 * kKeyframes);
    EXPECT_LT(run.registered, all.registered);
    EXPECT_GE(run.inter, 1);
}

// Registrations on four worker threads finish in any order, but their verdicts are applied in
// candidate order (PCM's input order): the same registrations, the same verified loops, the same
// accepted loops with the same transforms as on one thread. (With a place window the candidates
// themselves depend on the robots' arrival order, so two runs cannot be compared.)
TEST(FrontEndActors, RegistrationThreadsGiveTheOneThreadLoops) {
    LoopMatcherConfig config;  // no candidate cap: the candidates do not depend on arrival order
    config.registration_threads = 1;
    const FrontEndRun one = RunFrontEnd(config);
    config.registration_threads = 4;
    const FrontEndRun four = RunFrontEnd(config);
    EXPECT_GT(one.registered, 0);
    EXPECT_EQ(four.registered, one.registered);
    EXPECT_EQ(four.verified, one.verified);
    ASSERT_GE(one.accepted.size(), 1u);
    ASSERT_EQ(four.accepted.size(), one.accepted.size());
    for (const auto& [ends, loop] : one.accepted) {
        const auto it = four.accepted.find(ends);
        ASSERT_NE(it, four.accepted.end());
        EXPECT_TRUE(it->second.T_a_b.isApprox(loop.T_a_b, 1e-12));
        EXPECT_EQ(it->second.kappa, loop.kappa);
        EXPECT_EQ(it->second.tau, loop.tau);
    }
}

// One place (a window wider than the mission): after a cloud registered, later candidates of
// the robot pair are skipped; only failed registrations reopen the place for another request.
TEST(FrontEndActors, PlaceGateSkipsCandidatesOfAPlaceAlreadyVerified) {
    LoopMatcherConfig config;
    config.place_window = 1000;
    const FrontEndRun run = RunFrontEnd(config);
    EXPECT_GT(run.skipped, 0);
    EXPECT_LE(run.inter, 1);  // the place's one admitted candidate
    EXPECT_GE(run.clouds_requested, 1);
}

// A cloud reply carries the keyframe's cloud downsampled at the requester's registration voxel
// (both robots run the team's settings), not the full-resolution scan.
TEST(FrontEndActors, CloudReplyIsDownsampledAtTheRegistrationVoxel) {
    slam::SimulatorConfig sim;
    sim.seed = 1;
    const slam::MissionGenerator generator(sim);
    const slam::Keyframe keyframe = generator.Generate(0, 0).keyframe;
    for (const bool downsample : {true, false}) {
        zmq::context_t context;
        const std::vector<int> robots{0, 1};
        const TeamWiring w0 = InprocWiring(0, robots);
        LoopMatcherConfig config;
        config.registration.voxel_m = 0.4;
        config.downsample_replies = downsample;
        LoopMatcherActor matcher(context, w0, config);
        transport::Endpoint keyframes(context, ServerConfig(w0, Edge::kKeyframes));
        matcher.Start();
        ASSERT_TRUE(keyframes.WaitForSubscribers(1, std::chrono::seconds(5)));
        ASSERT_EQ(keyframes.Send(EncodeKeyframe(keyframe, 1)), transport::SendStatus::kSent);
        transport::Endpoint dealer(context, ClientConfig(InprocWiring(1, robots), Edge::kClouds, 0,
                                                         transport::Role::kDealer));
        std::optional<slam::PointCloudPtr> cloud;
        v1::CloudReply reply;
        const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
        while (!cloud && std::chrono::steady_clock::now() < deadline) {
            v1::CloudRequest request;
            *request.mutable_header() = MakeHeader(1, 1, 0);
            *request.mutable_pose_id() = ToProto(slam::PoseId{0, 0});
            request.set_request_id(7);
            dealer.Send(transport::Pack(request));
            if (auto m = dealer.Receive(std::chrono::milliseconds(200))) {
                cloud = DecodeCloudReply(*m, &reply);  // nullopt while the keyframe is not in
            }
        }
        ASSERT_TRUE(cloud.has_value());
        const std::size_t expected = downsample ? slam::VoxelDownsample(*keyframe.cloud, 0.4).size()
                                                : keyframe.cloud->size();
        EXPECT_EQ((*cloud)->size(), expected);
        EXPECT_EQ(reply.request_id(), 7u);
        if (downsample) {
            EXPECT_LT(2 * expected, keyframe.cloud->size());
        }
        matcher.Stop();
    }
}

// A peer that subscribed late gets the lower robot's end-of-descriptors marker before the
// descriptors re-sent to it (the publisher's periodic end can overtake its re-send). The marker
// counts the stream, so robot 1's matcher waits for the descriptors and checks them before it
// says end of loops; a descriptor with a broken body is dropped and counted, not waited for.
// Robot 0's descriptor publisher is the test's, to force that order.
TEST(FrontEndActors, EndMarkerOvertakingTheDescriptorsDoesNotEndTheMatcher) {
    slam::SimulatorConfig sim;
    sim.seed = 1;
    const slam::MissionGenerator generator(sim);
    zmq::context_t context;
    const std::vector<int> robots{0, 1};
    const TeamWiring w0 = InprocWiring(0, robots), w1 = InprocWiring(1, robots);
    auto source = [&generator](int r) {
        return [&generator, r, next = 0]() mutable -> std::optional<slam::Keyframe> {
            if (next >= kKeyframes) return std::nullopt;
            return generator.Generate(r, next++).keyframe;
        };
    };
    IngestConfig ingest0, ingest1;
    ingest0.local_subscribers = 1;  // robot 0's matcher (it serves the clouds)
    ingest1.local_subscribers = 2;
    LoopMatcherActor matcher0(context, w0, LoopMatcherConfig{});
    IngestActor source0(context, w0, source(0), ingest0);
    transport::Endpoint descriptors0(context, ServerConfig(w0, Edge::kDescriptors));
    LoopMatcherActor matcher1(context, w1, LoopMatcherConfig{});
    DescriptorActor descriptor1(context, w1, slam::ScanContextConfig{});
    IngestActor source1(context, w1, source(1), ingest1);
    transport::Endpoint loops1(context, ClientConfig(w0, Edge::kLoops, 1));
    const std::vector<NodeActor*> started{&matcher0, &matcher1, &descriptor1, &source0, &source1};
    for (NodeActor* a : started) a->Start();
    ASSERT_TRUE(descriptors0.WaitForSubscribers(2, std::chrono::seconds(10)));
    std::uint64_t sequence = 0;
    v1::Shutdown end;
    *end.mutable_header() = MakeHeader(0, ++sequence, 0);
    end.set_reason(kEndOfDescriptors);
    end.set_count(kKeyframes);
    ASSERT_EQ(descriptors0.Send(transport::Pack(end)), transport::SendStatus::kSent);

    // Robot 1's own stream ends; robot 0's is announced ended but nothing of it came: no end.
    int loops = 0;
    bool ended = false;
    auto drain = [&](std::chrono::milliseconds wait) {
        const auto until = std::chrono::steady_clock::now() + wait;
        while (!ended && std::chrono::steady_clock::now() < until) {
            while (auto m = loops1.Receive(std::chrono::milliseconds(10))) {
                if (auto loop = transport::Unpack<v1::LoopClosure>(*m)) {
                    loops += FromProto(*loop).has_value() ? 1 : 0;
                } else if (auto e = transport::Unpack<v1::Shutdown>(*m)) {
                    ended = ended || e->reason() == kEndOfLoops;
                }
            }
        }
    };
    const auto deadline = std::chrono::steady_clock::now() + kTimeout;
    while (!source1.Finished() && std::chrono::steady_clock::now() < deadline) {
        drain(std::chrono::milliseconds(50));
    }
    ASSERT_TRUE(source1.Finished());
    drain(std::chrono::milliseconds(1500));  // 15 matcher ticks
    EXPECT_FALSE(ended) << "the matcher ended without robot 0's descriptors";
    EXPECT_EQ(matcher1.CloudsRequested(), 0);

    // The descriptors arrive after their end marker (then the marker again, as the actor does).
    for (int i = 0; i < kKeyframes; ++i) {
        const slam::Keyframe keyframe = generator.Generate(0, i).keyframe;
        auto proto =
            ToProto(slam::MakeScanContext(*keyframe.cloud, slam::ScanContextConfig{}), {0, i});
        *proto.mutable_header() = MakeHeader(0, ++sequence, keyframe.stamp_ns);
        if (i == kKeyframes - 1) {  // its body is broken: dropped, counted, and not waited for
            proto.set_num_rings(proto.num_rings() + 1);
        }
        ASSERT_EQ(descriptors0.Send(transport::Pack(proto)), transport::SendStatus::kSent);
    }
    *end.mutable_header() = MakeHeader(0, ++sequence, 0);
    descriptors0.Send(transport::Pack(end));
    drain(kTimeout);
    EXPECT_TRUE(ended) << "robot 1's matcher never said end of loops";
    EXPECT_GE(loops, 1) << "robot 1 checked none of robot 0's descriptors before its end";
    EXPECT_GE(matcher1.CloudsRequested(), 1);
    for (auto a = started.rbegin(); a != started.rend(); ++a) {
        (*a)->Stop();  // joins: the counters are final
        const bool matcher = *a == &matcher0 || *a == &matcher1;
        EXPECT_EQ((*a)->Counters().dropped_malformed, matcher ? 1u : 0u) << (*a)->Name();
    }
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
