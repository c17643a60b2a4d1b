// Solver and certifier actors over real inproc sockets and real messages: two robots' solvers
// exchange public poses asynchronously and reach the central certified optimum, the anchor's
// certifier broadcasts a CERTIFIED verdict to both; a silent third robot stops nobody; in rounds
// mode a restarted robot rejoins its converged peer, rounds without a peer fall back, and a peer
// with another overlap depth is dropped.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <set>
#include <string>
#include <thread>
#include <utility>

#include "actors/certifier_actor.h"
#include "actors/convert.h"
#include "actors/solver_actor.h"
#include "tests/actors/solver_fixture.h"

namespace certislam::actors {
namespace {

constexpr double kPoseTolerance = 1e-5;
constexpr auto kTimeout = std::chrono::seconds(40);

SolverActorConfig Config(const TwoRobotProblem& p) {
    SolverActorConfig config;
    config.solver = p.config;
    return config;
}

bool WaitFor(const std::function<bool()>& done) {
    const auto deadline = std::chrono::steady_clock::now() + kTimeout;
    while (std::chrono::steady_clock::now() < deadline) {
        if (done()) return true;
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return false;
}

TEST(SolverActor, TwoRobotsOverInprocReachTheCertifiedCentralOptimum) {
    const TwoRobotProblem problem = MakeTwoRobotProblem(40, 6, 3);
    zmq::context_t context;
    const std::vector<int> robots{0, 1};
    CertifierActor certifier(context, InprocWiring(0, robots), {});
    std::vector<std::unique_ptr<SolverActor>> solvers;
    for (int r : robots) {
        solvers.push_back(
            std::make_unique<SolverActor>(context, InprocWiring(r, robots), Config(problem)));
    }
    certifier.Start();
    for (auto& s : solvers) s->Start();
    Feeder feeder(context, robots, 2);
    feeder.Feed(problem);

    const auto certified = [&](const SolverSnapshot& s) {
        return s.final && s.local_ok && s.report &&
               s.report->verdict() == v1::CERTIFICATE_VERDICT_CERTIFIED &&
               s.report->iteration() == 2 * 39 + 6;  // every edge in the certified graph
    };
    ASSERT_TRUE(WaitFor([&] {
        return certified(solvers[0]->Snapshot()) && certified(solvers[1]->Snapshot());
    })) << "no certified verdict on the whole graph";
    EXPECT_GE(certifier.Checks(), 1);
    const auto central = CentralSolution(problem);
    for (int r : robots) {
        const SolverSnapshot s = solvers[r]->Snapshot();
        EXPECT_EQ(s.anchor, 0);
        EXPECT_LE(s.report->lambda_min(), 1e-6);  // S has the gauge null space
        ASSERT_EQ(s.trajectory.size(), central[r].size());
        for (size_t i = 0; i < central[r].size(); ++i) {
            const Eigen::Matrix4d diff =
                s.trajectory[i].T_world_body.matrix() - central[r][i].matrix();
            EXPECT_LT(diff.cwiseAbs().maxCoeff(), kPoseTolerance) << "robot " << r << " pose " << i;
        }
        EXPECT_EQ(solvers[r]->Counters().dropped_malformed, 0u);
        EXPECT_GT(solvers[r]->BytesSentToPeers(), 0u);
    }
}

// A pose-graph source re-sends its loops to a subscriber that joined late, and repeats its end
// marker: the marker can come first. A counted end is not the end until the loops it counts are in.
TEST(SolverActor, CountedEndOfLoopsWaitsForTheLoopsItCounts) {
    const TwoRobotProblem problem = MakeTwoRobotProblem(20, 4, 3);
    zmq::context_t context;
    const std::vector<int> robots{0, 1};
    std::vector<std::unique_ptr<SolverActor>> solvers;
    for (int r : robots) {
        solvers.push_back(
            std::make_unique<SolverActor>(context, InprocWiring(r, robots), Config(problem)));
    }
    for (auto& s : solvers) s->Start();
    Feeder feeder(context, robots, 2);
    feeder.FeedKeyframes(problem);
    feeder.FeedLoopEnds(problem, true);
    const auto all_keyframes = [&] {
        return solvers[0]->Snapshot().num_poses == 20 && solvers[1]->Snapshot().num_poses == 20;
    };
    ASSERT_TRUE(WaitFor(all_keyframes));
    // The markers had time to arrive (inproc): a solver that took them as the end would be final
    // without a single loop.
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    for (auto& s : solvers) EXPECT_FALSE(s->Snapshot().final);

    feeder.FeedLoops(problem);
    feeder.FeedLoopEnds(problem, true);  // the source repeats its markers
    ASSERT_TRUE(
        WaitFor([&] { return solvers[0]->Snapshot().final && solvers[1]->Snapshot().final; }));
    std::set<std::pair<slam::PoseId, slam::PoseId>> ends;  // parallel loops merge
    for (const auto& l : problem.loops) ends.insert({l.a, l.b});
    for (auto& s : solvers) EXPECT_EQ(s->Snapshot().inter_robot_loops, int(ends.size()));
}

// Two asynchronous solvers converged at a loose tolerance; then a report whose S + eta D was PSD
// but whose bound was too loose (inconclusive with a bound). `refine_rel_grad_tol`: the rounds'
// refined tolerance the solvers step on to.
struct LooseBoundTeam {
    static constexpr double kLooseTolerance = 1e-3;  // relative: RBCD stops just below it
    TwoRobotProblem problem = MakeTwoRobotProblem(30, 4, 5);
    double f = 0.0;
    zmq::context_t context;
    std::unique_ptr<transport::Endpoint> anchor;  ///< the certifier's report stream
    std::vector<std::unique_ptr<SolverActor>> solvers;

    explicit LooseBoundTeam(double refine_rel_grad_tol) {
        problem.config.rbcd.rel_grad_tol = kLooseTolerance;
        const slam::PoseGraph graph =
            certify::BuildJointGraph(problem.odometry, problem.loops, problem.config.noise);
        f = certify::SolveCertifiedJoint(graph, certify::MissionSolverConfig{}).cost;
        const std::vector<int> robots{0, 1};
        anchor = std::make_unique<transport::Endpoint>(
            context, ServerConfig(InprocWiring(0, robots), Edge::kCertify));
        SolverActorConfig config = Config(problem);
        config.rounds.refine_rel_grad_tol = refine_rel_grad_tol;
        for (int r : robots) {
            solvers.push_back(
                std::make_unique<SolverActor>(context, InprocWiring(r, robots), config));
            solvers.back()->Start();
        }
        EXPECT_TRUE(anchor->WaitForSubscribers(2, std::chrono::seconds(5)));
        Feeder feeder(context, robots, 2);
        feeder.Feed(problem);
        EXPECT_TRUE(WaitFor([&] { return Below(kLooseTolerance * std::max(1.0, f)); }));
        std::this_thread::sleep_for(std::chrono::milliseconds(300));  // settled on each other's
        steps_before = solvers[0]->Snapshot().steps;
        v1::CertificateReport report;
        *report.mutable_header() = MakeHeader(0, 1, 0);
        report.set_verdict(v1::CERTIFICATE_VERDICT_INCONCLUSIVE);
        report.set_has_bound(true);
        EXPECT_EQ(anchor->Send(transport::Pack(report)), transport::SendStatus::kSent);
    }
    bool Below(double tol) const {
        for (const auto& s : solvers) {
            const SolverSnapshot snap = s->Snapshot();
            if (!snap.final || !snap.local_ok || !(snap.grad_norm <= tol)) return false;
        }
        return true;
    }
    std::uint64_t steps_before = 0;
};

// The bound is first order in the gradient: the asynchronous solvers step on to the rounds'
// refined tolerance, which moves their blocks and opens a new check.
TEST(SolverActor, InconclusiveBoundTightensTheAsynchronousTolerance) {
    const LooseBoundTeam team(SolverActorConfig{}.rounds.refine_rel_grad_tol);
    const double tightened_tol =
        SolverActorConfig{}.rounds.refine_rel_grad_tol * std::max(1.0, team.f);
    EXPECT_TRUE(WaitFor([&] { return team.Below(tightened_tol); }))
        << "block gradients " << team.solvers[0]->Snapshot().grad_norm << ", "
        << team.solvers[1]->Snapshot().grad_norm << " above " << tightened_tol;
}

// A refined tolerance the gradient cannot reach (round-off) has a budget of steps: then the
// solvers are converged at their configured tolerance again, and send their bundles.
TEST(SolverActor, UnreachableRefinementEndsAtTheConfiguredTolerance) {
    const LooseBoundTeam team(1e-30);
    ASSERT_TRUE(WaitFor([&] { return team.solvers[0]->Snapshot().steps > team.steps_before; }))
        << "the report started no refinement";
    EXPECT_TRUE(WaitFor([&] {
        return team.Below(LooseBoundTeam::kLooseTolerance * std::max(1.0, team.f));
    })) << "stuck refining";
}

// A certifier begins reading a neighbour's bundles when a round names it: the converged solver
// sends its bundle to the new reader at once, not at the heartbeat's re-send. Re-sends of an
// unchanged bundle are >= kFirstResend (1 s) apart, so a watching reader that sees the next
// bundle sooner than that after a new reader subscribed saw the prompt one, however loaded
// the machine is.
TEST(SolverActor, ANewBundleReaderGetsTheBundleWithoutWaitingForTheResend) {
    constexpr auto kResend = std::chrono::milliseconds(1000);  // SolverActor::kFirstResend
    constexpr int kReaders = 2;
    const TwoRobotProblem problem = MakeTwoRobotProblem(20, 4, 3);
    zmq::context_t context;
    const std::vector<int> robots{0, 1};
    std::vector<std::unique_ptr<SolverActor>> solvers;
    for (int r : robots) {
        solvers.push_back(
            std::make_unique<SolverActor>(context, InprocWiring(r, robots), Config(problem)));
        solvers.back()->Start();
    }
    Feeder feeder(context, robots, 2);
    feeder.Feed(problem);
    ASSERT_TRUE(WaitFor([&] {
        const auto a = solvers[0]->Snapshot(), b = solvers[1]->Snapshot();
        return a.final && b.final && a.local_ok && b.local_ok;
    }));
    const auto next_bundle = [](transport::Endpoint& reader, std::chrono::seconds within) {
        const auto until = std::chrono::steady_clock::now() + within;
        while (std::chrono::steady_clock::now() < until) {
            const auto m = reader.Receive(std::chrono::milliseconds(10));
            if (m && m->Is<v1::PublicPoses>()) return true;
        }
        return false;
    };
    transport::Endpoint watch(context, ClientConfig(InprocWiring(0, robots), Edge::kBundle, 1));
    ASSERT_TRUE(watch.WaitReady(std::chrono::seconds(5)));
    for (int k = 0; k < kReaders; ++k) {
        // Drain, then take the watch's next bundle: the solver's last send is just now.
        while (watch.Receive(std::chrono::milliseconds(0))) {
        }
        ASSERT_TRUE(next_bundle(watch, std::chrono::seconds(10))) << "no bundle re-sent";
        const auto previous = std::chrono::steady_clock::now();
        transport::Endpoint reader(context,
                                   ClientConfig(InprocWiring(0, robots), Edge::kBundle, 1));
        ASSERT_TRUE(reader.WaitReady(std::chrono::seconds(5)));
        ASSERT_TRUE(next_bundle(reader, std::chrono::seconds(10))) << "reader " << k;
        const auto gap = std::chrono::steady_clock::now() - previous;
        EXPECT_LT(gap, kResend)
            << "reader " << k << ": its bundle came "
            << std::chrono::duration_cast<std::chrono::milliseconds>(gap).count()
            << " ms after the previous one: a re-send, not the prompt bundle";
    }
}

SolverActorConfig RoundsConfig(const TwoRobotProblem& p) {
    SolverActorConfig config = Config(p);
    config.synchronous = true;  // a keyframe robot's solver.mode rounds
    config.async_until_final = true;
    return config;
}

// Max difference of a robot's trajectory from the central optimum (infinite when poses miss).
double OffCentral(const SolverSnapshot& s,
                  const std::vector<std::vector<Eigen::Isometry3d>>& central, int robot) {
    if (s.trajectory.size() != central[robot].size()) return INFINITY;
    double m = 0.0;
    for (size_t i = 0; i < central[robot].size(); ++i) {
        m = std::max(m, (s.trajectory[i].T_world_body.matrix() - central[robot][i].matrix())
                            .cwiseAbs()
                            .maxCoeff());
    }
    return m;
}

/// Inproc wiring, but a solver's poses and bundle streams on ipc: a peer that connected to them
/// reconnects when a new solver binds them again (an inproc connection ends with its binder).
TeamWiring RestartableWiring(int robot, const std::vector<int>& robots) {
    TeamWiring w = InprocWiring(robot, robots);
    for (int r : robots) {
        for (Edge edge : {Edge::kPoses, Edge::kBundle}) {
            w.addresses[r][edge] = "ipc://" + std::filesystem::temp_directory_path().string() +
                                   "/certislam_solver_test_" + std::to_string(getpid()) + "_r" +
                                   std::to_string(r) + "_" + std::to_string(int(edge));
        }
    }
    return w;
}

// Robot 1's solver is replaced by a new one (a restart: no rounds, a new incarnation) after the
// team's rounds converged and certified. Robot 0 opens a new round session, both sweep again, and
// the certificate runs again on the new session's result (before: robot 1 waited at round 0).
TEST(SolverActor, RestartedPeerRejoinsTheConvergedRoundsInANewSession) {
    const TwoRobotProblem problem = MakeTwoRobotProblem(30, 4, 5);
    zmq::context_t context;
    const std::vector<int> robots{0, 1};
    CertifierActor certifier(context, RestartableWiring(0, robots), {});
    std::vector<std::unique_ptr<SolverActor>> solvers;
    for (int r : robots) {
        solvers.push_back(std::make_unique<SolverActor>(context, RestartableWiring(r, robots),
                                                        RoundsConfig(problem)));
    }
    certifier.Start();
    for (auto& s : solvers) s->Start();
    Feeder feeder(context, robots, 2);
    feeder.Feed(problem);
    const auto certified = [](const SolverSnapshot& s, std::uint64_t session) {
        return s.rounds_converged && s.round_session == session && s.local_ok && s.report &&
               s.report->verdict() == v1::CERTIFICATE_VERDICT_CERTIFIED;
    };
    ASSERT_TRUE(WaitFor([&] {
        return certified(solvers[0]->Snapshot(), 0) && certified(solvers[1]->Snapshot(), 0);
    })) << "the team's first rounds did not converge";

    solvers[1].reset();
    ASSERT_TRUE(WaitFor([&] {  // the old sockets' inproc names are released by the context
        try {
            solvers[1] = std::make_unique<SolverActor>(context, RestartableWiring(1, robots),
                                                       RoundsConfig(problem));
            solvers[1]->Start();
            return true;
        } catch (const zmq::error_t&) {
            solvers[1].reset();
            return false;
        }
    }));
    ASSERT_TRUE(WaitFor([&] {  // re-fed until the new solver subscribed and has its graph
        feeder.Feed(problem);
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
        return solvers[1]->Snapshot().final;
    }));
    ASSERT_TRUE(WaitFor([&] {
        return certified(solvers[0]->Snapshot(), 1) && certified(solvers[1]->Snapshot(), 1);
    })) << "robot 0 in session "
        << solvers[0]->Snapshot().round_session << ", robot 1 in "
        << solvers[1]->Snapshot().round_session << " at " << solvers[1]->Snapshot().team_rounds
        << " rounds";
    const auto central = CentralSolution(problem);
    for (int r : robots) {
        EXPECT_LT(OffCentral(solvers[r]->Snapshot(), central, r), kPoseTolerance) << "robot " << r;
    }
}

// Robot 1 takes no part in rounds (asynchronous updates only): robot 0's rounds wait for it, and
// after rounds_stall without progress fall back to asynchronous updates, which reach the optimum.
TEST(SolverActor, RoundsWithoutProgressFallBackToAsynchronousUpdates) {
    const TwoRobotProblem problem = MakeTwoRobotProblem(20, 3, 6);
    zmq::context_t context;
    const std::vector<int> robots{0, 1};
    SolverActorConfig config = RoundsConfig(problem);
    config.rounds_stall = std::chrono::milliseconds(1000);
    SolverActor rounds(context, InprocWiring(0, robots), config);
    SolverActor asynchronous(context, InprocWiring(1, robots), Config(problem));
    rounds.Start();
    asynchronous.Start();
    Feeder feeder(context, robots, 2);
    feeder.Feed(problem);
    const auto central = CentralSolution(problem);
    ASSERT_TRUE(WaitFor([&] {
        const auto s = rounds.Snapshot();
        return s.final && s.rounds_gave_up && s.local_ok &&
               OffCentral(asynchronous.Snapshot(), central, 1) < 1e-4;
    })) << "robot 1 off the central optimum by "
        << OffCentral(asynchronous.Snapshot(), central, 1);
    EXPECT_FALSE(rounds.Snapshot().rounds_converged);
}

// Robot 1 is configured with other overlapping sweeps (solver.rounds_overlap) than robot 0: the
// one that hears the other's round poses drops them as malformed (counted), so the rounds stall
// and both fall back to asynchronous updates, which reach the optimum. Without the check the two
// sweep schedules mixed and never reached it.
TEST(SolverActor, PeerWithAnotherOverlapDepthIsDroppedAndCounted) {
    const TwoRobotProblem problem = MakeTwoRobotProblem(20, 3, 9);
    zmq::context_t context;
    const std::vector<int> robots{0, 1};
    std::vector<std::unique_ptr<SolverActor>> solvers;
    for (int r : robots) {
        SolverActorConfig config = RoundsConfig(problem);
        config.rounds_stall = std::chrono::milliseconds(1000);
        config.rounds.overlap_depth = r == 0 ? 2 : 4;  // neither is the proto's default 0
        solvers.push_back(std::make_unique<SolverActor>(context, InprocWiring(r, robots), config));
        solvers.back()->Start();
    }
    Feeder feeder(context, robots, 2);
    feeder.Feed(problem);
    const auto central = CentralSolution(problem);
    ASSERT_TRUE(WaitFor([&] {
        for (int r : robots) {
            const auto s = solvers[r]->Snapshot();
            if (!s.final || !s.rounds_gave_up || !s.local_ok ||
                OffCentral(s, central, r) > kPoseTolerance) {
                return false;
            }
        }
        return true;
    })) << "robot 1 off the central optimum by "
        << OffCentral(solvers[1]->Snapshot(), central, 1);
    std::uint64_t dropped = 0;  // by the robot that heard a round first (the sweep order's)
    for (int r : robots) {
        EXPECT_FALSE(solvers[r]->Snapshot().rounds_converged) << "robot " << r;
        dropped += solvers[r]->Counters().dropped_malformed;
    }
    EXPECT_GT(dropped, 0u);
}

TEST(SolverActor, SilentNeighbourDoesNotStopTheOthers) {
    // Robots 0 and 1 meet; robot 2 is configured but never starts. 0 and 1 still converge on
    // their blocks (never certified: robot 2's bundle never comes).
    const TwoRobotProblem problem = MakeTwoRobotProblem(30, 4, 8);
    zmq::context_t context;
    const std::vector<int> team{0, 1, 2};
    std::vector<std::unique_ptr<SolverActor>> solvers;
    for (int r : {0, 1}) {
        solvers.push_back(
            std::make_unique<SolverActor>(context, InprocWiring(r, team), Config(problem)));
        solvers.back()->Start();
    }
    Feeder feeder(context, {0, 1}, 2);
    feeder.Feed(problem);
    const auto central = CentralSolution(problem);
    // Converged: both blocks locally optimal and robot 1's poses at the central optimum (the
    // snapshot is taken while the robots still iterate, so wait for it rather than sample once).
    const auto max_diff = [&](const SolverSnapshot& s) {
        double m = 0.0;
        for (size_t i = 0; i < central[1].size() && i < s.trajectory.size(); ++i) {
            m = std::max(m, (s.trajectory[i].T_world_body.matrix() - central[1][i].matrix())
                                .cwiseAbs()
                                .maxCoeff());
        }
        return m;
    };
    ASSERT_TRUE(WaitFor([&] {
        const auto a = solvers[0]->Snapshot(), b = solvers[1]->Snapshot();
        return a.num_poses == 30 && b.num_poses == 30 && a.local_ok && b.local_ok &&
               a.inter_robot_loops == 4 && b.inter_robot_loops == 4 && max_diff(b) < 1e-4;
    })) << "robot 1 off the central optimum by "
        << max_diff(solvers[1]->Snapshot());
    const auto s = solvers[1]->Snapshot();
    EXPECT_FALSE(s.final);  // robot 2's matcher never said end of loops
    EXPECT_FALSE(s.report.has_value());
    for (size_t i = 0; i < central[1].size(); ++i) {
        const Eigen::Matrix4d diff = s.trajectory[i].T_world_body.matrix() - central[1][i].matrix();
        EXPECT_LT(diff.cwiseAbs().maxCoeff(), 1e-4);
    }
}

}  // namespace
}  // namespace certislam::actors
