// Certifier actors of 2-3 robots over real inproc and tcp sockets, fed converged bundles by
// stand-in solvers (real publishers on each robot's bundle edge, real protobuf messages): in the
// distributed mode every robot reaches the centralised lambda_min itself (only entries of v at
// public poses and partial sums travel), at a certified optimum and at a known saddle; the
// anchor's certificate (the central rule on the round's sums) has the central check's verdict,
// objective, duality gap and lower bound to 1e-9; the centralised mode reports the same; a round
// whose eigen-solve ran out of steps without a verdict is checked by the anchor at once.
#include <gtest/gtest.h>
#include <unistd.h>

#include <memory>
#include <optional>
#include <string>
#include <thread>

#include "actors/certifier_actor.h"
#include "certify/certificate.h"
#include "certify/staircase.h"
#include "slam/backend/chordal.h"
#include "slam/backend/connection_laplacian.h"
#include "slam/core/partition.h"
#include "tests/certify/test_graphs.h"

namespace certislam::actors {
namespace {

constexpr double kLambdaTolerance = 1e-7;  ///< |distributed - centralised| / ||Q||
constexpr double kAgree = 1e-9;  ///< objective, gap and bound: |distributed - central| / f
constexpr auto kTimeout = std::chrono::seconds(30);
constexpr auto kResend = std::chrono::milliseconds(300);

/// A joint problem split into robots: the graph with PoseIds and the team's X.
struct TeamProblem {
    slam::PoseGraph graph;
    Eigen::MatrixXd X;
    slam::Partition partition;
};

TeamProblem Split(slam::PoseGraph graph, Eigen::MatrixXd X, int robots) {
    TeamProblem p{std::move(graph), std::move(X), {}};
    p.partition = slam::ContiguousPartition(p.graph.n, robots);
    p.graph.ids.clear();
    for (int g = 0; g < p.graph.n; ++g) {
        const int r = p.partition.RobotOf(g);
        p.graph.ids.push_back({r, g - p.partition.begin[r]});
    }
    return p;
}

/// A noisy sphere solved to its certified optimum (rank from the staircase).
TeamProblem CertifiedSphere(int robots) {
    Eigen::MatrixXd truth;
    const slam::PoseGraph graph = certify::testing::NoisySphere(4, 8, 0.02, 0.05, 11, &truth);
    const slam::Partition partition = slam::ContiguousPartition(graph.n, robots);
    const auto solved = certify::SolveCertified(
        graph, partition, slam::LiftToRank(slam::ChordalInitialization(graph), graph.d));
    EXPECT_EQ(solved.status, certify::StaircaseResult::Status::kCertified);
    return Split(graph, solved.X, robots);
}

/// The twisted critical point of an identity cycle: a saddle (tests/certify uses it too).
TeamProblem TwistedSaddle(int robots) {
    return Split(certify::testing::IdentityCycle(3, 8), certify::testing::TwistedCycle(3, 8),
                 robots);
}

TeamWiring Wiring(int robot, int robots, bool tcp) {
    std::vector<int> team;
    for (int r = 0; r < robots; ++r) team.push_back(r);
    TeamWiring w = InprocWiring(robot, team);
    if (!tcp) return w;
    // Below Linux's ephemeral range (32768-60999), apart from test_bin_distributed's 20000-32000:
    // a client retrying a port not yet bound cannot be handed that port as its source.
    const int base = 32000 + static_cast<int>(getpid() % 30) * 25;  // 3 robots: 24 ports
    for (int r = 0; r < robots; ++r) {
        int port = base + 8 * r;
        for (auto& [edge, address] : w.addresses[r]) {
            if (edge != Edge::kKeyframes) address = "tcp://127.0.0.1:" + std::to_string(++port);
        }
    }
    return w;
}

/// Plays every robot's solver: its converged bundle (status, own edges, block), again and again.
class BundleFeeder {
  public:
    BundleFeeder(zmq::context_t& context, const TeamProblem& p, bool tcp) : p_(p) {
        for (int r = 0; r < p.partition.num_robots(); ++r) {
            out_.push_back(std::make_unique<transport::Endpoint>(
                context, ServerConfig(Wiring(r, p.partition.num_robots(), tcp), Edge::kBundle)));
        }
    }
    void SendAll() {
        for (int r = 0; r < p_.partition.num_robots(); ++r) Send(r);
    }

  private:
    void Send(int r) {
        const int n = p_.partition.size(r), first = p_.partition.begin[r];
        v1::SolverStatus status;
        *status.mutable_header() = MakeHeader(r, ++sequence_, 0);
        status.set_phase(v1::SolverStatus::PHASE_CONVERGED);
        status.set_num_poses(static_cast<std::uint32_t>(n));
        status.set_rank_r(static_cast<std::uint32_t>(p_.X.rows()));
        out_[r]->Send(transport::Pack(status));
        for (const auto& e : p_.graph.edges) {
            if (p_.partition.RobotOf(e.i) != r) continue;  // an edge travels with its tail
            slam::LoopClosure l;
            l.a = p_.graph.ids[e.i];
            l.b = p_.graph.ids[e.j];
            l.T_a_b.linear() = e.R;
            l.T_a_b.translation() = e.t;
            l.kappa = e.kappa;
            l.tau = e.tau;
            auto proto = ToProto(l);
            *proto.mutable_header() = MakeHeader(r, ++sequence_, 0);
            out_[r]->Send(transport::Pack(proto));
        }
        certify::PoseBlocks block;
        for (int i = 0; i < n; ++i) block.ids.push_back({r, i});
        block.blocks = p_.X.middleCols(4 * first, 4 * n);
        auto proto = ToProto(block);
        *proto.mutable_header() = MakeHeader(r, ++sequence_, 0);
        out_[r]->Send(transport::Pack(proto));
    }

    const TeamProblem& p_;
    std::vector<std::unique_ptr<transport::Endpoint>> out_;
    std::uint64_t sequence_ = 0;
};

struct Case {
    const char* name;
    bool tcp;
    int robots;
    bool saddle;
};

class CertifierTeam : public ::testing::TestWithParam<Case> {};

/// What a team's certifiers concluded: every robot's round, and the anchor's certificate.
struct TeamResult {
    std::vector<certify::DistributedVerdict> verdicts;  ///< robot order
    std::optional<certify::CertificateResult> anchor;   ///< decided by the central rule
};

/// Runs the certifiers until every robot has a verdict.
TeamResult RunTeam(const TeamProblem& p, bool tcp) {
    zmq::context_t context;
    CertifierConfig config;
    config.max_staircase_steps = 0;
    std::vector<std::unique_ptr<CertifierActor>> certifiers;
    const int robots = p.partition.num_robots();
    for (int r = 0; r < robots; ++r) {
        certifiers.push_back(
            std::make_unique<CertifierActor>(context, Wiring(r, robots, tcp), config));
    }
    BundleFeeder feeder(context, p, tcp);
    for (auto& c : certifiers) c->Start();
    const auto deadline = std::chrono::steady_clock::now() + kTimeout;
    bool all = false;
    while (!all && std::chrono::steady_clock::now() < deadline) {
        feeder.SendAll();
        std::this_thread::sleep_for(kResend);
        all = true;
        for (auto& c : certifiers) all = all && c->LastVerdict().has_value();
        all = all && certifiers.front()->LastCertificate().has_value();
    }
    TeamResult out;
    for (auto& c : certifiers) {
        c->Stop();
        if (c->LastVerdict()) out.verdicts.push_back(*c->LastVerdict());
    }
    out.anchor = certifiers.front()->LastCertificate();
    return out;
}

TEST_P(CertifierTeam, EveryRobotReachesTheCentralisedLambdaMin) {
    const Case& c = GetParam();
    const TeamProblem p = c.saddle ? TwistedSaddle(c.robots) : CertifiedSphere(c.robots);
    const auto central =
        certify::Certify(slam::ConnectionLaplacian(p.graph), p.X, 3, certify::CertificateConfig{});
    ASSERT_EQ(central.status, c.saddle ? certify::CertificateResult::Status::kNotOptimal
                                       : certify::CertificateResult::Status::kCertified);
    const TeamResult team = RunTeam(p, c.tcp);
    const auto& verdicts = team.verdicts;
    ASSERT_EQ(static_cast<int>(verdicts.size()), c.robots) << "a robot got no verdict";
    // The anchor's certificate: the central check's verdict, objective, gap and bound.
    ASSERT_TRUE(team.anchor.has_value());
    EXPECT_EQ(team.anchor->status, central.status) << team.anchor->reason;
    EXPECT_NEAR(team.anchor->objective, central.objective, kAgree * central.objective);
    EXPECT_NEAR(team.anchor->duality_gap, central.duality_gap, kAgree * central.objective);
    EXPECT_EQ(team.anchor->has_bound, central.has_bound);
    EXPECT_NEAR(team.anchor->lower_bound, central.lower_bound, kAgree * central.objective);
    for (size_t r = 0; r < verdicts.size(); ++r) {
        const certify::DistributedVerdict& v = verdicts[r];
        EXPECT_EQ(v.round, verdicts.front().round) << "robot " << r;
        EXPECT_EQ(v.status, certify::DistributedVerdict::Status::kConverged)
            << "robot " << r << " lambda_min " << v.lambda_min;
        if (c.saddle) {
            EXPECT_LT(v.lambda_min, 0.0) << "robot " << r;
        }
        EXPECT_NEAR(v.lambda_min, central.lambda_min, kLambdaTolerance * central.q_norm)
            << "robot " << r;
        EXPECT_DOUBLE_EQ(v.lambda_min, verdicts.front().lambda_min) << "robot " << r;
        EXPECT_NEAR(v.q_norm, central.q_norm, 1e-12 * central.q_norm);
        EXPECT_NEAR(v.cost, central.objective, 1e-9 * std::max(1.0, central.objective));
        EXPECT_GT(v.steps, 0);
        EXPECT_GT(v.entries_sent, 0.0) << "robot " << r << " sent no entries of v";
    }
}

/// The anchor's first CertificateReport as a solver hears it, with the certifiers' `config`;
/// `fallbacks`: the anchor's Fallbacks() then; `last`: its LastCertificate() then.
std::optional<v1::CertificateReport> AnchorReport(
    const TeamProblem& p, const CertifierConfig& config, int* fallbacks = nullptr,
    std::optional<certify::CertificateResult>* last = nullptr) {
    zmq::context_t context;
    const int robots = p.partition.num_robots();
    std::vector<std::unique_ptr<CertifierActor>> certifiers;
    for (int r = 0; r < robots; ++r) {
        certifiers.push_back(
            std::make_unique<CertifierActor>(context, Wiring(r, robots, false), config));
    }
    transport::Endpoint solver(context, ClientConfig(Wiring(1, robots, false), Edge::kCertify, 0));
    BundleFeeder feeder(context, p, false);
    for (auto& c : certifiers) c->Start();
    const auto deadline = std::chrono::steady_clock::now() + kTimeout;
    std::optional<v1::CertificateReport> report;
    while (!report && std::chrono::steady_clock::now() < deadline) {
        feeder.SendAll();
        const auto until = std::chrono::steady_clock::now() + kResend;
        while (!report && std::chrono::steady_clock::now() < until) {
            const auto m = solver.Receive(std::chrono::milliseconds(50));
            if (m && m->Is<v1::CertificateReport>())
                report = transport::Unpack<v1::CertificateReport>(*m);
        }
    }
    if (fallbacks) *fallbacks = certifiers.front()->Fallbacks();
    if (last) *last = certifiers.front()->LastCertificate();
    for (auto& c : certifiers) c->Stop();
    return report;
}

/// The anchor's report in one mode, without saddle escapes.
std::optional<v1::CertificateReport> AnchorReport(const TeamProblem& p, bool distributed) {
    CertifierConfig config;
    config.max_staircase_steps = 0;
    config.distributed = distributed;
    return AnchorReport(p, config);
}

TEST(CertifierModes, CentralisedAndDistributedReportTheSameVerdictToTheSolvers) {
    for (const bool saddle : {false, true}) {
        const TeamProblem p = saddle ? TwistedSaddle(2) : CertifiedSphere(2);
        const auto central = certify::Certify(slam::ConnectionLaplacian(p.graph), p.X, 3);
        const auto expected =
            saddle ? v1::CERTIFICATE_VERDICT_NOT_CERTIFIED : v1::CERTIFICATE_VERDICT_CERTIFIED;
        for (const bool distributed : {false, true}) {
            const auto report = AnchorReport(p, distributed);
            ASSERT_TRUE(report.has_value()) << "no report, distributed " << distributed;
            EXPECT_EQ(report->verdict(), expected) << "distributed " << distributed;
            EXPECT_NEAR(report->lambda_min(), central.lambda_min, kLambdaTolerance * central.q_norm)
                << "distributed " << distributed;
            EXPECT_EQ(report->iteration(), p.graph.edges.size());
            // One X, one graph: the central objective, gap and bound, whichever mode.
            EXPECT_NEAR(report->objective(), central.objective, kAgree * central.objective);
            EXPECT_NEAR(report->duality_gap(), central.duality_gap, kAgree * central.objective);
            EXPECT_EQ(report->has_bound(), central.has_bound);
            EXPECT_NEAR(report->lower_bound(), central.lower_bound, kAgree * central.objective);
            EXPECT_NEAR(report->relative_suboptimality_bound(),
                        central.relative_suboptimality_bound, kAgree);
        }
    }
}

TEST(CertifierFallback, ARoundWhoseEigenSolveRanOutOfStepsIsCheckedCentrallyAtOnce) {
    // At a saddle S + eta D does not factorize, so a round without lambda_min has no verdict; the
    // bundles never change here, so no later round would give one.
    const TeamProblem p = TwistedSaddle(2);
    const auto central = certify::Certify(slam::ConnectionLaplacian(p.graph), p.X, 3);
    ASSERT_EQ(central.status, certify::CertificateResult::Status::kNotOptimal);
    CertifierConfig config;
    config.max_staircase_steps = 0;
    config.lanczos.lobpcg.max_iterations = 1;
    config.round_timeout = std::chrono::milliseconds(60000);  // not the silent-round fallback
    int fallbacks = 0;
    std::optional<certify::CertificateResult> last;
    const auto report = AnchorReport(p, config, &fallbacks, &last);
    ASSERT_TRUE(report.has_value()) << "no report: the team would wait for its timeout";
    EXPECT_EQ(report->path(), v1::CERTIFICATE_PATH_FALLBACK);
    EXPECT_EQ(report->verdict(), v1::CERTIFICATE_VERDICT_NOT_CERTIFIED);
    EXPECT_NEAR(report->lambda_min(), central.lambda_min, kLambdaTolerance * central.q_norm);
    EXPECT_EQ(fallbacks, 1);
    // The anchor's last certificate is the one it reported, not the inconclusive round's.
    ASSERT_TRUE(last.has_value());
    EXPECT_EQ(last->status, certify::CertificateResult::Status::kNotOptimal);
    EXPECT_DOUBLE_EQ(last->lambda_min, report->lambda_min());
}

/// Sends every bundle for `period` (one batch per kResend).
void FeedFor(BundleFeeder& feeder, std::chrono::milliseconds period) {
    const auto until = std::chrono::steady_clock::now() + period;
    while (std::chrono::steady_clock::now() < until) {
        feeder.SendAll();
        std::this_thread::sleep_for(kResend);
    }
}

TEST(CertifierSettled, NoNewRoundForASettledSolutionUntilTheGraphChanges) {
    constexpr double kTinyMove = 1e-9;  ///< relative block move, far below settled_move_relative
    constexpr auto kQuiet = std::chrono::milliseconds(2000);  ///< several round lengths
    TeamProblem p = CertifiedSphere(2);
    zmq::context_t context;
    CertifierConfig config;
    config.max_staircase_steps = 0;
    std::vector<std::unique_ptr<CertifierActor>> certifiers;
    for (int r = 0; r < 2; ++r) {
        certifiers.push_back(
            std::make_unique<CertifierActor>(context, Wiring(r, 2, false), config));
    }
    BundleFeeder feeder(context, p, false);
    for (auto& c : certifiers) c->Start();
    const CertifierActor& anchor = *certifiers[0];
    const auto deadline = std::chrono::steady_clock::now() + kTimeout;
    while (!anchor.LastCertificate() && std::chrono::steady_clock::now() < deadline) {
        FeedFor(feeder, kResend);
    }
    ASSERT_TRUE(anchor.LastVerdict().has_value());
    ASSERT_TRUE(anchor.LastCertificate().has_value());
    ASSERT_EQ(anchor.LastCertificate()->status, certify::CertificateResult::Status::kCertified);
    const int rounds = anchor.Rounds();

    // The solvers' blocks still creep after the verdict: new bundles, no new round.
    p.X *= 1.0 + kTinyMove;
    FeedFor(feeder, kQuiet);
    EXPECT_GE(anchor.SettledSkips(), 1) << "the moved bundles were not noticed";
    EXPECT_EQ(anchor.Rounds(), rounds) << "a settled solution was checked again";

    // A new edge (a second copy of the first inter-robot one): the graph changed, a round runs.
    for (const auto& e : p.graph.edges) {
        if (p.partition.RobotOf(e.i) != p.partition.RobotOf(e.j)) {
            p.graph.edges.push_back(e);
            break;
        }
    }
    const auto again = std::chrono::steady_clock::now() + kTimeout;
    while (anchor.Rounds() == rounds && std::chrono::steady_clock::now() < again) {
        FeedFor(feeder, kResend);
    }
    EXPECT_GT(anchor.Rounds(), rounds) << "a new edge did not re-open the check";
    for (auto& c : certifiers) c->Stop();
}

INSTANTIATE_TEST_SUITE_P(Transports, CertifierTeam,
                         ::testing::Values(Case{"inproc_2_certified", false, 2, false},
                                           Case{"inproc_3_saddle", false, 3, true},
                                           Case{"tcp_3_certified", true, 3, false},
                                           Case{"tcp_2_saddle", true, 2, true}),
                         [](const ::testing::TestParamInfo<Case>& info) {
                             return std::string(info.param.name);
                         });

}  // namespace
}  // namespace certislam::actors
