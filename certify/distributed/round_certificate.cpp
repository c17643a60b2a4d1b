// A distributed round's verdict by the central rules, and the whole check over plain data.
#include "certify/distributed/round_certificate.h"

#include <map>
#include <optional>
#include <string>

#include "slam/backend/connection_laplacian.h"
#include "slam/core/check.h"
#include "slam/core/loop_closure.h"

namespace certislam::certify {
namespace {

constexpr int kD = 3;  ///< the robots' problems are 3D (LocalCertificateProblem)

/// The loop closure of measurement `e` between the poses named by graph.ids.
slam::LoopClosure EdgeOf(const slam::PoseGraph& graph, const slam::RelativePoseMeasurement& e) {
    slam::LoopClosure out;
    out.a = graph.ids[static_cast<size_t>(e.i)];
    out.b = graph.ids[static_cast<size_t>(e.j)];
    out.T_a_b.linear() = e.R;
    out.T_a_b.translation() = e.t;
    out.kappa = e.kappa;
    out.tau = e.tau;
    return out;
}

}  // namespace

CertificateResult DecideRound(const DistributedVerdict& round, const CertificateConfig& config,
                              const PsdTestFunction& psd_at) {
    config.Validate();
    CertificateResult result;
    const CertificateQuantities q = QuantitiesOf(round);
    const bool critical = FirstOrderVerdict(q, config, &result);
    result.eigen_iterations = round.steps;
    result.eigen_residual = round.residual_estimate;
    const auto inconclusive = [&](const std::string& why) {
        result.status = CertificateResult::Status::kInconclusive;
        result.reason = why;
        return result;
    };
    if (round.status == DistributedVerdict::Status::kInconsistent) {
        return inconclusive("a neighbour's entries of v did not cover the poses a robot reads");
    }
    if (!critical) return result;  // kNotCritical: no eigenvalue, no bound
    if (round.status == DistributedVerdict::Status::kNotCritical) {
        return inconclusive("the round stopped at a first-order tolerance other than config's");
    }
    const bool converged = round.status == DistributedVerdict::Status::kConverged;
    SecondOrderVerdict(q, converged ? std::optional<double>(round.lambda_min) : std::nullopt,
                       config, psd_at, &result);
    return result;
}

PsdTestFunction RoundPsdTest(const Eigen::SparseMatrix<double>& Q, const Eigen::MatrixXd& X) {
    return MakePsdTest(CertificateMatrix(Q, LambdaBlocks(Q, X, kD), kD), kD);
}

LocalCertificateProblem LocalProblemOf(const slam::PoseGraph& graph, const Eigen::MatrixXd& X,
                                       const slam::Partition& partition, int robot) {
    CERTISLAM_CHECK(graph.d == kD && static_cast<int>(graph.ids.size()) == graph.n);
    const int b = kD + 1;
    const int first = partition.begin[robot];
    std::vector<slam::PoseId> own(graph.ids.begin() + first,
                                  graph.ids.begin() + partition.begin[robot + 1]);
    std::vector<slam::LoopClosure> edges;
    std::map<slam::PoseId, Eigen::MatrixXd> far;
    for (const auto& e : graph.edges) {
        const bool mine_i = partition.RobotOf(e.i) == robot;
        const bool mine_j = partition.RobotOf(e.j) == robot;
        if (!mine_i && !mine_j) continue;
        edges.push_back(EdgeOf(graph, e));
        for (const int g : {e.i, e.j}) {
            if (partition.RobotOf(g) != robot) {
                far[graph.ids[static_cast<size_t>(g)]] = X.middleCols(b * g, b);
            }
        }
    }
    LocalCertificateProblem problem;
    const bool ok = MakeLocalProblem(robot, own, X.middleCols(b * first, b * partition.size(robot)),
                                     edges, far, &problem);
    CERTISLAM_CHECK(ok);
    return problem;
}

DistributedCertificate CertifyDistributed(const slam::PoseGraph& graph, const Eigen::MatrixXd& X,
                                          const slam::Partition& partition,
                                          const CertificateConfig& config,
                                          LanczosSettings settings) {
    settings.eta_relative = config.eta_relative;
    settings.gradient_tolerance_relative = config.gradient_tolerance_relative;
    std::vector<LocalCertificateProblem> problems;
    problems.reserve(static_cast<size_t>(partition.num_robots()));
    for (int k = 0; k < partition.num_robots(); ++k) {
        problems.push_back(LocalProblemOf(graph, X, partition, k));
    }
    DistributedCertificate out;
    for (const auto& p : RunInMemory(problems, settings)) out.robots.push_back(p->Verdict());
    const Eigen::SparseMatrix<double> Q = slam::ConnectionLaplacian(graph);
    out.certificate = DecideRound(out.robots.front(), config, RoundPsdTest(Q, X));
    return out;
}

}  // namespace certislam::certify
