// Certifier actors of two robots over real tcp sockets on loopback, fed by stand-in solvers that
// keep the solvers' protocol (real publishers on each robot's bundle edge, real protobuf): a
// bundle goes out once, and again only when a certifier asks (BundleRequest). A verdict that is
// not certified is followed by a new round once a solver's bundle changed, even a change it did
// not send; a restarted anchor asks for every bundle and reaches a verdict again; a bundle cut
// short by a solver's restart is asked for again.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "actors/certifier_actor.h"
#include "certify/staircase.h"
#include "certislam/v1/certificate.pb.h"
#include "slam/backend/chordal.h"
#include "slam/core/partition.h"
#include "tests/certify/test_graphs.h"

namespace certislam::actors {
namespace {

constexpr auto kTimeout = std::chrono::seconds(30);
constexpr auto kPoll = std::chrono::milliseconds(10);
constexpr int kRobots = 2;
constexpr int kBindAttempts = 50;  ///< 100 ms apart

/// A sphere solved to its certified optimum, split into two robots, and a point of the same
/// graph that is not first-order critical (the chordal start at the same rank).
struct Problem {
    slam::PoseGraph graph;
    slam::Partition partition;
    Eigen::MatrixXd certified, not_critical;
};

Problem MakeProblem() {
    Problem p;
    Eigen::MatrixXd truth;
    p.graph = certify::testing::NoisySphere(4, 8, 0.02, 0.05, 11, &truth);
    p.partition = slam::ContiguousPartition(p.graph.n, kRobots);
    const Eigen::MatrixXd start = slam::LiftToRank(slam::ChordalInitialization(p.graph), p.graph.d);
    const auto solved = certify::SolveCertified(p.graph, p.partition, start);
    EXPECT_EQ(solved.status, certify::StaircaseResult::Status::kCertified);
    p.certified = solved.X;
    p.not_critical = Eigen::MatrixXd::Zero(solved.X.rows(), start.cols());
    p.not_critical.topRows(start.rows()) = start;
    p.graph.ids.clear();
    for (int g = 0; g < p.graph.n; ++g) {
        const int r = p.partition.RobotOf(g);
        p.graph.ids.push_back({r, g - p.partition.begin[r]});
    }
    return p;
}

/// Loopback tcp wiring above Linux's ephemeral range (32768-60999), apart from the other tests'.
TeamWiring Wiring(int robot) {
    TeamWiring w = InprocWiring(robot, {0, 1});
    const int base = 61000 + static_cast<int>(getpid() % 200) * 20;  // 2 robots: 16 ports
    for (int r = 0; r < kRobots; ++r) {
        int port = base + 8 * r;
        for (auto& [edge, address] : w.addresses[r]) {
            if (edge != Edge::kKeyframes) address = "tcp://127.0.0.1:" + std::to_string(++port);
        }
    }
    return w;
}

/// Plays both robots' solvers as the solver actor does: a bundle when it changes (Send), and the
/// current one to every BundleRequest naming the robot; hears the anchor's reports.
class StandInSolvers {
  public:
    StandInSolvers(zmq::context_t& context, const Problem& p, Eigen::MatrixXd X)
        : p_(p), X_(std::move(X)) {
        for (int r = 0; r < kRobots; ++r) {
            out_.push_back(std::make_unique<transport::Endpoint>(
                context, ServerConfig(Wiring(r), Edge::kBundle)));
            in_.push_back(std::make_unique<transport::Endpoint>(
                context, ClientConfig(Wiring(0), Edge::kCertify, r)));
        }
    }
    /// The block every later bundle carries (sent only when asked for, or by Send).
    void Set(Eigen::MatrixXd X) { X_ = std::move(X); }
    /// Robot r's whole bundle: status, own edges, block; without its block when `cut_short`.
    void Send(int r, bool cut_short = false) {
        const int n = p_.partition.size(r), first = p_.partition.begin[r];
        v1::SolverStatus status;
        *status.mutable_header() = MakeHeader(r, ++sequence_, 0);
        status.set_phase(v1::SolverStatus::PHASE_CONVERGED);
        status.set_num_poses(static_cast<std::uint32_t>(n));
        status.set_rank_r(static_cast<std::uint32_t>(X_.rows()));
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
        if (cut_short) return;
        certify::PoseBlocks block;
        for (int i = 0; i < n; ++i) block.ids.push_back({r, i});
        block.blocks = X_.middleCols(4 * first, 4 * n);
        auto proto = ToProto(block);
        *proto.mutable_header() = MakeHeader(r, ++sequence_, 0);
        out_[r]->Send(transport::Pack(proto));
    }
    /// Answers requests and collects reports until `done` or the timeout; true when `done`.
    bool PollUntil(const std::function<bool()>& done) {
        const auto deadline = std::chrono::steady_clock::now() + kTimeout;
        while (!done() && std::chrono::steady_clock::now() < deadline) {
            for (auto& in : in_) {
                const auto m = in->Receive(kPoll);
                if (m) Handle(*m);
            }
        }
        return done();
    }
    /// Drops every request and report heard so far, unanswered.
    void Drain() {
        for (auto& in : in_) {
            while (in->Receive(kPoll)) {
            }
        }
    }
    const std::vector<v1::CertificateReport>& Reports() const { return reports_; }
    /// BundleRequests heard since the last report that was not certified.
    int RequestsSinceUncertified() const { return requests_since_uncertified_; }
    /// Called with every report heard (before it is kept).
    std::function<void(const v1::CertificateReport&)> on_report;

  private:
    void Handle(const transport::Message& m) {
        if (m.Is<v1::CertificateReport>()) {
            const auto report = transport::Unpack<v1::CertificateReport>(m);
            if (!report) return;
            if (on_report) on_report(*report);
            if (report->verdict() != v1::CERTIFICATE_VERDICT_CERTIFIED) {
                requests_since_uncertified_ = 0;
            }
            reports_.push_back(*report);
            return;
        }
        if (!m.Is<v1::BundleRequest>()) return;
        const auto request = transport::Unpack<v1::BundleRequest>(m);
        if (!request) return;
        ++requests_since_uncertified_;
        for (const auto r : request->robot_ids()) {
            if (int(r) < kRobots) Send(int(r));
        }
    }

    const Problem& p_;
    Eigen::MatrixXd X_;
    std::vector<std::unique_ptr<transport::Endpoint>> out_, in_;
    std::vector<v1::CertificateReport> reports_;
    int requests_since_uncertified_ = 0;
    std::uint64_t sequence_ = 0;
};

CertifierConfig Config() {
    CertifierConfig config;
    config.max_staircase_steps = 0;
    return config;
}

bool HasCertified(const std::vector<v1::CertificateReport>& reports) {
    return std::any_of(reports.begin(), reports.end(), [](const v1::CertificateReport& r) {
        return r.verdict() == v1::CERTIFICATE_VERDICT_CERTIFIED;
    });
}

TEST(CertifierActorBundles, UncertifiedVerdictIsFollowedByANewRoundOnAChangedBundle) {
    const Problem p = MakeProblem();
    zmq::context_t context;
    StandInSolvers solvers(context, p, p.not_critical);
    CertifierActor anchor(context, Wiring(0), Config());
    CertifierActor other(context, Wiring(1), Config());
    // After the first verdict (not critical) the solvers move on to the optimum but send nothing
    // (a change no flag marked, or a bundle lost on the way): only a certifier's ask brings it.
    bool moved = false;
    solvers.on_report = [&](const v1::CertificateReport& report) {
        if (moved || report.verdict() == v1::CERTIFICATE_VERDICT_CERTIFIED) return;
        solvers.Set(p.certified);
        moved = true;
    };
    anchor.Start();
    other.Start();
    for (int r = 0; r < kRobots; ++r) solvers.Send(r);
    ASSERT_TRUE(solvers.PollUntil([&] { return !solvers.Reports().empty(); })) << "no verdict";
    EXPECT_NE(solvers.Reports().front().verdict(), v1::CERTIFICATE_VERDICT_CERTIFIED);
    const int rounds = anchor.Rounds();
    ASSERT_TRUE(solvers.PollUntil([&] { return HasCertified(solvers.Reports()); }))
        << "no new round after the verdict " << solvers.Reports().back().verdict();
    EXPECT_GE(solvers.RequestsSinceUncertified(), 1) << "the anchor never asked again";
    EXPECT_GT(anchor.Rounds(), rounds);
    EXPECT_TRUE(other.LastVerdict().has_value());
}

TEST(CertifierActorBundles, RestartedAnchorAsksForEveryBundleAndCertifiesAgain) {
    const Problem p = MakeProblem();
    zmq::context_t context;
    StandInSolvers solvers(context, p, p.certified);
    auto anchor = std::make_unique<CertifierActor>(context, Wiring(0), Config());
    CertifierActor other(context, Wiring(1), Config());
    anchor->Start();
    other.Start();
    for (int r = 0; r < kRobots; ++r) solvers.Send(r);
    ASSERT_TRUE(solvers.PollUntil([&] { return HasCertified(solvers.Reports()); }));
    // The anchor's process dies and comes back with nothing; the solvers have converged and send
    // no bundle of their own any more.
    anchor->Stop();
    anchor.reset();
    // Its port is free once ZeroMQ's I/O thread has closed the old listener (as for a process
    // restarted at once): the new anchor retries its bind like a supervisor would.
    for (int attempt = 0; attempt < kBindAttempts; ++attempt) {
        anchor = std::make_unique<CertifierActor>(context, Wiring(0), Config());
        try {
            anchor->Start();
            break;
        } catch (const std::exception&) {
            anchor.reset();
            std::this_thread::sleep_for(std::chrono::milliseconds(100));
        }
    }
    ASSERT_TRUE(anchor) << "the restarted anchor could not bind its port";
    ASSERT_TRUE(solvers.PollUntil([&] { return anchor->LastCertificate().has_value(); }))
        << "the restarted anchor never reached a verdict";
    EXPECT_EQ(anchor->LastCertificate()->status, certify::CertificateResult::Status::kCertified)
        << anchor->LastCertificate()->reason;
    anchor->Stop();
}

TEST(CertifierActorBundles, BundleCutShortByARestartIsAskedForAgain) {
    const Problem p = MakeProblem();
    zmq::context_t context;
    StandInSolvers solvers(context, p, p.certified);
    CertifierActor anchor(context, Wiring(0), Config());
    CertifierActor other(context, Wiring(1), Config());
    anchor.Start();
    other.Start();
    // Robot 1's solver dies between its status and its block; the restarted one has converged
    // to the same block and answers only the requests sent after that.
    std::this_thread::sleep_for(std::chrono::milliseconds(500));  // both subscribed by now
    solvers.Send(0);
    solvers.Send(1, true);
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    solvers.Drain();
    ASSERT_TRUE(solvers.PollUntil([&] { return HasCertified(solvers.Reports()); }))
        << "the anchor waited for the rest of a bundle that never came";
    anchor.Stop();
    other.Stop();
}

}  // namespace
}  // namespace certislam::actors
