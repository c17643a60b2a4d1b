// The verdict of a distributed round by the one central rule: the team's sums (cost, tr(Lambda),
// gradient, ||X||) and the Lanczos lambda_min of one X on one graph, decided by
// FirstOrderVerdict and SecondOrderVerdict (certify/certificate.h) with a PSD test of S + e D of
// that graph, so its duality gap and bound are the central check's (MATH.md, "What a report may
// claim").
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <vector>

#include "certify/certificate.h"
#include "certify/distributed/distributed_lanczos.h"
#include "slam/core/partition.h"
#include "slam/core/pose_graph.h"

namespace certislam::certify {

/// The certificate of a finished round: status, bound and every quantity from `round` (any
/// robot's: they are identical) and psd_at, the Cholesky test of S + e D of the round's graph at
/// its X (RoundPsdTest). A round that stopped early or disagreed is inconclusive, with a reason.
CertificateResult DecideRound(const DistributedVerdict& round, const CertificateConfig& config,
                              const PsdTestFunction& psd_at);

/// The PSD test of S + e D for S = Q - Lambda(X) of a graph (d = 3).
PsdTestFunction RoundPsdTest(const Eigen::SparseMatrix<double>& Q, const Eigen::MatrixXd& X);

/// Robot `robot`'s problem from a joint graph whose ids name (robot, index) with each robot's
/// poses contiguous in `partition` order: its block of X, the edges at its poses and the
/// neighbours' blocks at their far ends (what the certifier actor builds from bundles).
LocalCertificateProblem LocalProblemOf(const slam::PoseGraph& graph, const Eigen::MatrixXd& X,
                                       const slam::Partition& partition, int robot);

/// The distributed certificate over plain data: one LocalProblemOf per robot, one round run in
/// memory (RunInMemory), decided by DecideRound with the PSD test of the joint graph.
struct DistributedCertificate {
    CertificateResult certificate;           ///< the verdict and bound
    std::vector<DistributedVerdict> robots;  ///< every robot's round result
};
DistributedCertificate CertifyDistributed(const slam::PoseGraph& graph, const Eigen::MatrixXd& X,
                                          const slam::Partition& partition,
                                          const CertificateConfig& config = {},
                                          LanczosSettings settings = {});

}  // namespace certislam::certify
