// The message-driven distributed Lanczos over plain data: 2, 4 and 8 robots (contiguous split)
// reach the smallest eigenvalue of S that the centralised shift-invert solver finds
// (certify/min_eigenpair), on real g2o graphs and on hand-built saddles (d = 2, 3); and its
// messages follow the protocol (only neighbours read vectors, every robot the same verdict).
#include "certify/distributed/distributed_lanczos.h"

#include <gtest/gtest.h>

#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "certify/certificate.h"
#include "certify/min_eigenpair.h"
#include "slam/backend/chordal.h"
#include "slam/backend/connection_laplacian.h"
#include "slam/io/g2o_io.h"
#include "tests/certify/test_graphs.h"
#include "tests/data_paths.h"

namespace certislam::certify {
namespace {

constexpr double kLambdaTolerance = 1e-8;  ///< |distributed - centralised| / ||Q||
constexpr int kRank = 5;                   ///< rank of the lifted X the checks run at

/// The centralised reference and the distributed answer at one X, for one split.
struct Comparison {
    double central = 0.0;
    double q_norm = 0.0;
    DistributedEigenResult distributed;
};

Comparison Compare(const slam::PoseGraph& graph, const Eigen::MatrixXd& X, int robots) {
    const int d = graph.d;
    const Eigen::SparseMatrix<double> Q = slam::ConnectionLaplacian(graph);
    const Eigen::SparseMatrix<double> S = CertificateMatrix(Q, LambdaBlocks(Q, X, d), d);
    const MinEigenpairResult central = SmallestEigenpair(S);
    EXPECT_EQ(central.status, MinEigenpairResult::Status::kConverged);
    const slam::Partition partition = slam::ContiguousPartition(graph.n, robots);
    std::vector<CertificateRows> rows;
    for (int k = 0; k < robots; ++k) rows.push_back(MakeCertificateRows(Q, X, d, partition, k));
    LanczosSettings settings;
    settings.max_krylov = static_cast<int>(Q.rows());
    return {central.lambda, NormUpperBound(Q), DistributedMinEigenpair(rows, settings)};
}

void ExpectAgrees(const Comparison& c, const std::string& what) {
    EXPECT_EQ(c.distributed.status, DistributedEigenResult::Status::kConverged) << what;
    EXPECT_NEAR(c.distributed.lambda_min, c.central, kLambdaTolerance * c.q_norm)
        << what << ": distributed " << c.distributed.lambda_min << " central " << c.central;
    EXPECT_LT(c.distributed.residual, 1e-6 * c.q_norm) << what;
    EXPECT_GT(c.distributed.entries_exchanged, 0.0) << what;
}

slam::PoseGraph Read(const std::string& name) {
    const auto read = slam::ReadG2o(test_data::G2oPath(name));
    EXPECT_TRUE(read.ok()) << read.error;
    return read.graph;
}

class RealGraph : public ::testing::TestWithParam<int> {};

TEST_P(RealGraph, SmallGrid3DAtTheChordalStartMatchesTheCentralSolver) {
    const slam::PoseGraph graph = Read("smallGrid3D.g2o");
    const Eigen::MatrixXd X = slam::LiftToRank(slam::ChordalInitialization(graph), kRank);
    ExpectAgrees(Compare(graph, X, GetParam()), "smallGrid3D");
}

TEST_P(RealGraph, TinyGrid3DAtTheChordalStartMatchesTheCentralSolver) {
    const slam::PoseGraph graph = Read("tinyGrid3D.g2o");
    const Eigen::MatrixXd X = slam::LiftToRank(slam::ChordalInitialization(graph), kRank);
    ExpectAgrees(Compare(graph, X, GetParam()), "tinyGrid3D");
}

INSTANTIATE_TEST_SUITE_P(Robots, RealGraph, ::testing::Values(2, 4, 8));

TEST(HandBuiltGraph, TwistedCycleSaddleOnTwoFourAndEightRobotsIn2DAnd3D) {
    const int n = 16;
    for (const int d : {2, 3}) {
        const slam::PoseGraph graph = testing::IdentityCycle(d, n);
        const Eigen::MatrixXd X = testing::TwistedCycle(d, n);
        for (const int robots : {2, 4, 8}) {
            const Comparison c = Compare(graph, X, robots);
            ASSERT_LT(c.central, 0.0);  // a saddle: S has a negative eigenvalue
            ExpectAgrees(c, "d = " + std::to_string(d) + ", " + std::to_string(robots) + " robots");
        }
    }
}

TEST(HandBuiltGraph, RitzVectorIsAUnitEigenvectorSplitByRobot) {
    const int d = 3, n = 16;
    const slam::PoseGraph graph = testing::IdentityCycle(d, n);
    const Comparison c = Compare(graph, testing::TwistedCycle(d, n), 4);
    ASSERT_EQ(c.distributed.vector.size(), 4u);
    double norm_sq = 0.0;
    for (const auto& segment : c.distributed.vector) {
        EXPECT_EQ(segment.size(), (d + 1) * n / 4);
        norm_sq += segment.squaredNorm();
    }
    EXPECT_NEAR(norm_sq, 1.0, 1e-12);
}

TEST(Participant, EveryRobotReachesTheSameVerdictAndOnlyNeighboursReadVectors) {
    // Drive three participants by hand on a cycle split 0 | 1 | 2: every robot has both others
    // as neighbours, so each vector goes to two readers; sums go to everyone.
    const int d = 3, n = 6;
    const slam::PoseGraph graph = testing::IdentityCycle(d, n);
    const Eigen::MatrixXd X = testing::TwistedCycle(d, n);
    const Eigen::SparseMatrix<double> Q = slam::ConnectionLaplacian(graph);
    const slam::Partition partition = slam::ContiguousPartition(n, 3);
    std::vector<LocalCertificateProblem> problems(3);
    for (int k = 0; k < 3; ++k) {
        problems[k].robot = k;
        problems[k].rows = MakeCertificateRows(Q, X, d, partition, k);
        for (int g : problems[k].rows.public_poses) problems[k].public_ids.push_back({k, g});
        for (int g : problems[k].rows.neighbor_poses) {
            const int owner = g / 2;
            problems[k].neighbor_ids.push_back({owner, g});
            problems[k].neighbor_robots.insert(owner);
        }
    }
    struct Mail {
        bool vector;
        int from, step, stage;
        std::vector<slam::PoseId> ids;
        Eigen::VectorXd values;
        std::vector<double> sums;
    };
    std::vector<Mail> outbox;
    std::vector<std::unique_ptr<LanczosParticipant>> robots;
    for (int k = 0; k < 3; ++k) {
        robots.push_back(std::make_unique<LanczosParticipant>(
            problems[k], std::vector<int>{0, 1, 2}, 7, LanczosSettings{},
            [&, k](int step, const std::vector<slam::PoseId>& ids, const Eigen::VectorXd& v) {
                outbox.push_back({true, k, step, 0, ids, v, {}});
            },
            [&, k](int step, int stage, const std::vector<double>& sums) {
                outbox.push_back({false, k, step, stage, {}, {}, sums});
            }));
    }
    for (auto& r : robots) r->Begin();
    int delivered = 0;
    while (!outbox.empty()) {
        const Mail m = outbox.front();
        outbox.erase(outbox.begin());
        if (m.vector) {
            EXPECT_EQ(m.values.size(), (d + 1) * static_cast<int>(m.ids.size()));
        }
        for (int to = 0; to < 3; ++to) {
            if (to == m.from) continue;
            if (m.vector) {
                robots[to]->OnVector(m.from, m.step, m.ids, m.values);
            } else {
                robots[to]->OnReduction(m.from, m.step, m.stage, m.sums);
            }
            ++delivered;
        }
    }
    EXPECT_GT(delivered, 0);
    const CertificateResult central = Certify(Q, X, d);
    for (const auto& r : robots) {
        ASSERT_TRUE(r->Done());
        EXPECT_EQ(r->Verdict().round, 7u);
        EXPECT_EQ(r->Verdict().status, DistributedVerdict::Status::kConverged);
        EXPECT_LT(r->Verdict().lambda_min, 0.0);  // a saddle (round_certificate_test decides)
        EXPECT_EQ(r->Verdict().lambda_min, robots.front()->Verdict().lambda_min);  // bit for bit
        EXPECT_NEAR(r->Verdict().lambda_min, central.lambda_min, kLambdaTolerance * central.q_norm);
        EXPECT_NEAR(r->Verdict().dual_value, central.dual_value,
                    1e-9 * std::abs(central.dual_value));
    }
}

TEST(Settings, RejectsABadFieldByName) {
    LanczosSettings settings;
    settings.check_every = 0;
    try {
        settings.Validate();
        FAIL() << "check_every = 0 accepted";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("check_every"), std::string::npos) << e.what();
    }
}

}  // namespace
}  // namespace certislam::certify
