// The loop matcher's PCM in the loop, over real inproc sockets: two robots' ingest, descriptor,
// matcher and solver actors on a simulated mission where some of robot 1's keyframes carry a
// cloud copied from a far-away place of robot 0 (perceptual aliasing: registration accepts the
// false loop); a false loop sent on the loop stream is withdrawn, and the solvers' graphs end
// with only true ones. And a solver over sockets: a withdrawal removes a loop, a stale verdict or a
// re-broadcast does not bring it back, a newer accept does.
#include <gtest/gtest.h>

#include <memory>
#include <set>
#include <thread>

#include "actors/convert.h"
#include "actors/descriptor_actor.h"
#include "actors/ingest_actor.h"
#include "actors/loop_matcher_actor.h"
#include "actors/solver_actor.h"
#include "certislam/v1/control.pb.h"
#include "slam/sim/simulator.h"

namespace certislam::actors {
namespace {

constexpr int kKeyframes = 60;
constexpr double kTrueLoopTolerance_m = 0.5;
constexpr double kAliasMinDistance_m = 10.0;  // an aliased cloud comes from this far away
constexpr auto kTimeout = std::chrono::seconds(90);
// Robot 1's keyframe -> robot 0's keyframe whose cloud it carries instead of its own.
const std::map<int, int> kAliased{{12, 45}, {33, 3}, {51, 21}};  // queried: % stride 3

bool IsTrue(const slam::MissionGenerator& g, const slam::LoopClosure& l) {
    const Eigen::Isometry3d T_true = g.T_world_sensor_truth(l.a.robot, l.a.index).inverse() *
                                     g.T_world_sensor_truth(l.b.robot, l.b.index);
    return (T_true.inverse() * l.T_a_b).translation().norm() < kTrueLoopTolerance_m;
}

template <typename Pred>
bool WaitFor(Pred pred, std::chrono::milliseconds timeout) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (!pred()) {
        if (std::chrono::steady_clock::now() > deadline) return false;
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return true;
}

// A subscriber that joins after robot 1's matcher sent its loops (a restarted robot's solver) gets
// every accepted loop again, and an end marker that counts the inter-robot ones.
void ExpectALateSubscriberHearsEveryLoop(zmq::context_t& context, const std::vector<int>& robots,
                                         const LoopMatcherActor& matcher, int accepted_inter) {
    transport::Endpoint late(context, ClientConfig(InprocWiring(0, robots), Edge::kLoops, 1));
    std::set<std::pair<slam::PoseId, slam::PoseId>> resent;
    std::optional<std::uint64_t> counted;
    const auto late_deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while ((!counted || resent.size() < static_cast<size_t>(matcher.LoopsFound())) &&
           std::chrono::steady_clock::now() < late_deadline) {
        while (auto m = late.Receive(std::chrono::milliseconds(10))) {
            if (auto proto = transport::Unpack<v1::LoopClosure>(*m)) {
                if (auto loop = FromProto(*proto)) resent.insert({loop->a, loop->b});
            } else if (auto end = transport::Unpack<v1::Shutdown>(*m)) {
                if (end->reason() == kEndOfLoops) counted = end->count();
            }
        }
    }
    EXPECT_EQ(static_cast<int>(resent.size()), matcher.LoopsFound());
    ASSERT_TRUE(counted.has_value()) << "no end of loops after the late subscriber joined";
    EXPECT_EQ(static_cast<int>(*counted), accepted_inter);
}

// Incremental PCM may send an aliased loop while it is the largest consistent set it has (the
// order registrations finish in depends on load), but must withdraw it once the true loops
// outvote it: no false loop stays with the solvers.
TEST(LoopMatcherActors, AliasedKeyframesMakeFalseLoopsThatDoNotStayWithTheSolvers) {
    slam::SimulatorConfig sim;
    sim.seed = 1;
    const slam::MissionGenerator g(sim);
    for (const auto& [j, x] : kAliased) {  // the aliasing is real: the places are far apart
        ASSERT_GT((g.T_world_sensor_truth(1, j).translation() -
                   g.T_world_sensor_truth(0, x).translation())
                      .norm(),
                  kAliasMinDistance_m);
    }
    zmq::context_t context;
    const std::vector<int> robots{0, 1};
    std::vector<std::unique_ptr<NodeActor>> actors;
    std::vector<SolverActor*> solvers;
    std::vector<LoopMatcherActor*> matchers;
    for (int r : robots) {
        const TeamWiring w = InprocWiring(r, robots);
        SolverActorConfig solver;
        solver.solver.rbcd.rel_grad_tol = 1e-6;
        auto s = std::make_unique<SolverActor>(context, w, solver);
        solvers.push_back(s.get());
        actors.push_back(std::move(s));
        auto m = std::make_unique<LoopMatcherActor>(context, w, LoopMatcherConfig{});
        matchers.push_back(m.get());
        actors.push_back(std::move(m));
        actors.push_back(std::make_unique<DescriptorActor>(context, w, slam::ScanContextConfig{}));
        auto next = std::make_shared<int>(0);
        auto source = [&g, r, next]() -> std::optional<slam::Keyframe> {
            if (*next >= kKeyframes) return std::nullopt;
            const int i = (*next)++;
            slam::Keyframe kf = g.Generate(r, i).keyframe;
            if (r == 1 && kAliased.count(i))
                kf.cloud = g.Generate(0, kAliased.at(i)).keyframe.cloud;
            return kf;
        };
        actors.push_back(std::make_unique<IngestActor>(context, w, source, IngestConfig{}));
    }
    transport::Endpoint listener(context, ClientConfig(InprocWiring(0, robots), Edge::kLoops, 1));
    for (auto& a : actors) a->Start();

    std::vector<slam::LoopClosure> sent;
    std::multiset<std::pair<slam::PoseId, slam::PoseId>> withdrawn;  // one per withdrawal sent
    bool ended = false;
    const auto deadline = std::chrono::steady_clock::now() + kTimeout;
    while (!ended && std::chrono::steady_clock::now() < deadline) {
        while (auto m = listener.Receive(std::chrono::milliseconds(10))) {
            if (auto proto = transport::Unpack<v1::LoopClosure>(*m)) {
                if (const auto ends = WithdrawnEnds(*proto)) {
                    withdrawn.insert(*ends);
                } else if (auto loop = FromProto(*proto)) {
                    sent.push_back(*loop);
                }
            } else if (auto end = transport::Unpack<v1::Shutdown>(*m)) {
                ended = ended || end->reason() == kEndOfLoops;
            }
        }
    }
    ASSERT_TRUE(ended) << "robot 1's matcher never said end of loops";
    int inter = 0;
    for (const auto& l : sent) {
        EXPECT_TRUE(IsTrue(g, l) || withdrawn.count({l.a, l.b}) + withdrawn.count({l.b, l.a}) > 0)
            << "false loop never withdrawn: keyframes " << l.a.index << "-" << l.b.index;
        inter += l.inter_robot() ? 1 : 0;
    }
    EXPECT_GE(inter, 2);
    // Registration accepted some aliased pairs: PCM, not registration, kept them out.
    EXPECT_GT(matchers[1]->Verified(), matchers[1]->LoopsFound());
    const auto withdrawals = static_cast<int>(withdrawn.size());
    EXPECT_EQ(withdrawals, matchers[1]->Withdrawn());
    EXPECT_EQ(matchers[1]->LoopsFound(), static_cast<int>(sent.size()) - withdrawals);
    const int accepted_inter = inter - withdrawals;  // every solver ends with exactly these
    for (auto* s : solvers) {
        EXPECT_TRUE(WaitFor([&] { return s->Snapshot().inter_robot_loops == accepted_inter; },
                            std::chrono::seconds(5)))
            << "solver has " << s->Snapshot().inter_robot_loops << ", matcher accepted "
            << accepted_inter;
    }
    ExpectALateSubscriberHearsEveryLoop(context, robots, *matchers[1], accepted_inter);
    for (auto& a : actors) EXPECT_EQ(a->Counters().dropped_malformed, 0u) << a->Name();
    for (auto& a : actors) a->Stop();
}

void SendLoop(transport::Endpoint& out, v1::LoopClosure proto, std::int64_t version,
              std::uint64_t* sequence) {
    *proto.mutable_header() = MakeHeader(1, ++*sequence, version);
    ASSERT_EQ(out.Send(transport::Pack(proto)), transport::SendStatus::kSent);
}

TEST(LoopMatcherActors, WithdrawalReachesTheSolverAndStaleVerdictsDoNotUndoIt) {
    zmq::context_t context;
    const std::vector<int> robots{0, 1};
    const TeamWiring w = InprocWiring(0, robots);
    transport::Endpoint keyframes(context, ServerConfig(w, Edge::kKeyframes));
    transport::Endpoint loops(context, ServerConfig(InprocWiring(1, robots), Edge::kLoops));
    SolverActor solver(context, w, SolverActorConfig{});
    solver.Start();
    ASSERT_TRUE(keyframes.WaitForSubscribers(1, std::chrono::seconds(5)));
    ASSERT_TRUE(loops.WaitForSubscribers(1, std::chrono::seconds(5)));
    for (int i = 0; i < 10; ++i) {
        slam::Keyframe kf;
        kf.robot = 0;
        kf.index = i;
        kf.T_odom_sensor.translation() = Eigen::Vector3d(2.0 * i, 0, 0);
        kf.cloud = std::make_shared<slam::PointCloud>(10, Eigen::Vector3f(1, 2, 3));
        ASSERT_EQ(keyframes.Send(EncodeKeyframe(kf, static_cast<std::uint64_t>(i + 1))),
                  transport::SendStatus::kSent);
    }
    ASSERT_TRUE(
        WaitFor([&] { return solver.Snapshot().num_poses == 10; }, std::chrono::seconds(5)));
    slam::LoopClosure loop;
    loop.a = {0, 4};
    loop.b = {1, 2};
    loop.T_a_b.translation() = Eigen::Vector3d(1, 0, 0);
    std::uint64_t seq = 0;
    const auto count = [&] { return solver.Snapshot().inter_robot_loops; };
    const auto settle = [] { std::this_thread::sleep_for(std::chrono::milliseconds(400)); };
    SendLoop(loops, ToProto(loop), 100, &seq);
    ASSERT_TRUE(WaitFor([&] { return count() == 1; }, std::chrono::seconds(5)));
    SendLoop(loops, LoopWithdrawal(loop.a, loop.b), 200, &seq);
    ASSERT_TRUE(WaitFor([&] { return count() == 0; }, std::chrono::seconds(5)));
    SendLoop(loops, ToProto(loop), 0, &seq);    // a solver's re-broadcast of the old accept
    SendLoop(loops, ToProto(loop), 150, &seq);  // an accept older than the withdrawal
    settle();
    EXPECT_EQ(count(), 0);
    SendLoop(loops, ToProto(loop), 300, &seq);  // the matcher accepts it again
    EXPECT_TRUE(WaitFor([&] { return count() == 1; }, std::chrono::seconds(5)));
    solver.Stop();
    EXPECT_EQ(solver.Counters().dropped_malformed, 0u);
}

}  // namespace
}  // namespace certislam::actors
