// CertifyLocalSearch: one-block RBCD at rank d on f, then Certify.
#include "certify/local_search.h"

#include "slam/backend/connection_laplacian.h"
#include "slam/core/check.h"
#include "slam/core/partition.h"

namespace certislam::certify {

void LocalSearchPolishConfig::Validate() const {
    rbcd.Validate();
    certificate.Validate();
}

LocalSearchCertificate CertifyLocalSearch(const slam::PoseGraph& graph,
                                          const slam::PoseMatrix& poses,
                                          const LocalSearchPolishConfig& config) {
    config.Validate();
    CERTISLAM_CHECK(poses.rows() == graph.d && poses.cols() == (graph.d + 1) * graph.n);
    const Eigen::SparseMatrix<double> Q = slam::ConnectionLaplacian(graph);
    LocalSearchCertificate out;
    out.input_cost = slam::LiftedCost(Q, poses);
    const slam::RbcdResult polished =
        slam::SolveRbcd(graph, slam::ContiguousPartition(graph.n, 1), poses, config.rbcd);
    out.poses = polished.X;
    out.polish_iterations = polished.iterations;
    out.certificate = Certify(Q, out.poses, graph.d, config.certificate);
    return out;
}

}  // namespace certislam::certify
