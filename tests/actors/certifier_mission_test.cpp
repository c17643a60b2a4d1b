// The distributed certificate inside the actor graph: two robots' solver and certifier actors
// over real inproc sockets on a hand-built two-robot mission (tests/actors/solver_fixture.h),
// the certifiers in their default distributed mode with the 5 s fallback kept. Both solvers must
// hear a CERTIFIED verdict on the whole graph within a bound, produced by a distributed round
// (report path, no fallback), both robots must reach the same lambda_min, and it must equal the
// centralised check of the round's graph within eta (1e-7 ||Q||).
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <set>
#include <thread>

#include "actors/certifier_actor.h"
#include "actors/solver_actor.h"
#include "tests/actors/solver_fixture.h"

namespace certislam::actors {
namespace {

constexpr auto kVerdictBound = std::chrono::seconds(30);  ///< loops in -> certified verdict
constexpr auto kSettle = std::chrono::seconds(10);        ///< a round in flight finishes
constexpr double kLambdaRelative = 1e-7;  ///< |lambda - central lambda| <= this ||Q|| (= eta)
constexpr int kKeyframes = 100;           ///< per robot: S is 800 x 800 at rank 5
constexpr int kLoops = 8;                 ///< inter-robot loops

bool WaitFor(std::chrono::seconds bound, const std::function<bool()>& done) {
    const auto deadline = std::chrono::steady_clock::now() + bound;
    while (std::chrono::steady_clock::now() < deadline) {
        if (done()) return true;
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return false;
}

TEST(CertifierMission, DistributedRoundsCertifyATwoRobotMissionInTime) {
    const TwoRobotProblem problem = MakeTwoRobotProblem(kKeyframes, kLoops, 5);
    zmq::context_t context;
    const std::vector<int> robots{0, 1};
    CertifierConfig certifier_config;  // distributed by default
    certifier_config.cross_check = true;
    ASSERT_TRUE(certifier_config.distributed);
    SolverActorConfig solver_config;
    solver_config.solver = problem.config;
    std::vector<std::unique_ptr<CertifierActor>> certifiers;
    std::vector<std::unique_ptr<SolverActor>> solvers;
    for (int r : robots) {
        certifiers.push_back(
            std::make_unique<CertifierActor>(context, InprocWiring(r, robots), certifier_config));
        solvers.push_back(
            std::make_unique<SolverActor>(context, InprocWiring(r, robots), solver_config));
    }
    for (auto& c : certifiers) c->Start();
    for (auto& s : solvers) s->Start();
    Feeder feeder(context, robots, 2);
    const auto start = std::chrono::steady_clock::now();
    feeder.Feed(problem);

    std::set<std::pair<slam::PoseId, slam::PoseId>> loops;  // the fixture repeats some
    for (const auto& l : problem.loops) loops.insert({l.a, l.b});
    const std::uint64_t edges = 2 * (kKeyframes - 1) + loops.size();
    const auto certified = [&](const SolverSnapshot& s) {
        return s.final && s.local_ok && s.report &&
               s.report->verdict() == v1::CERTIFICATE_VERDICT_CERTIFIED &&
               s.report->iteration() == edges;  // every edge in the certified graph
    };
    ASSERT_TRUE(WaitFor(
        kVerdictBound,
        [&] { return certified(solvers[0]->Snapshot()) && certified(solvers[1]->Snapshot()); }))
        << "no certified verdict on the whole graph within the bound; rounds "
        << certifiers[0]->Rounds() << ", fallbacks " << certifiers[0]->Fallbacks() << ", last: "
        << (certifiers[0]->LastCertificate() ? certifiers[0]->LastCertificate()->reason : "none");
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    RecordProperty("seconds_to_certified", std::to_string(seconds));
    std::printf("certified after %.2f s, %d rounds at the anchor\n", seconds,
                certifiers[0]->Rounds());
    for (auto& s : solvers) {
        EXPECT_EQ(s->Snapshot().report->path(), v1::CERTIFICATE_PATH_DISTRIBUTED);
        s->Stop();  // no new bundles: the rounds stop
    }
    EXPECT_EQ(certifiers[0]->Fallbacks(), 0) << "a round fell back to the centralised check";

    // Both robots finish the same last round; its lambda_min is the centralised one.
    ASSERT_TRUE(WaitFor(kSettle, [&] {
        const auto a = certifiers[0]->LastVerdict(), b = certifiers[1]->LastVerdict();
        return a && b && a->round == b->round && a->central_lambda_min;
    })) << "the robots' last rounds differ";
    const certify::DistributedVerdict anchor = *certifiers[0]->LastVerdict();
    const certify::DistributedVerdict other = *certifiers[1]->LastVerdict();
    std::printf("last round: %d Lanczos steps, lambda_min %.3e (central %.3e), ||Q|| %.3e\n",
                anchor.steps, anchor.lambda_min, *anchor.central_lambda_min, anchor.q_norm);
    EXPECT_EQ(anchor.status, certify::DistributedVerdict::Status::kConverged);
    ASSERT_TRUE(certifiers[0]->LastCertificate().has_value());
    EXPECT_EQ(certifiers[0]->LastCertificate()->status,
              certify::CertificateResult::Status::kCertified);
    EXPECT_EQ(other.status, anchor.status);
    EXPECT_EQ(other.lambda_min, anchor.lambda_min);  // the same sums in the same order
    EXPECT_GT(anchor.q_norm, 0.0);
    EXPECT_NEAR(anchor.lambda_min, *anchor.central_lambda_min, kLambdaRelative * anchor.q_norm)
        << "steps " << anchor.steps;
    EXPECT_GT(anchor.steps, 0);
    EXPECT_GT(anchor.entries_sent, 0.0);
    for (auto& c : certifiers) {
        EXPECT_GE(c->Rounds(), 1);
        EXPECT_GT(c->BundleBytesFromPeers(), 0u);  // each reads its neighbour's bundles
    }
}

}  // namespace
}  // namespace certislam::actors
