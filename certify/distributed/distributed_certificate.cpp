// Robot-held rows of S: built from the joint Q and X, or from one robot's view of the graph.
#include "certify/distributed/distributed_certificate.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include "certify/certificate.h"
#include "slam/backend/connection_laplacian.h"
#include "slam/core/check.h"

namespace certislam::certify {
namespace {

constexpr int kBlock = 4;  ///< columns per pose of a robot's local problem, d + 1 with d = 3
constexpr double kEpsilon = std::numeric_limits<double>::epsilon();

}  // namespace

CertificateRows MakeCertificateRows(const Eigen::SparseMatrix<double>& Q, const Eigen::MatrixXd& X,
                                    int d, const slam::Partition& partition, int robot) {
    CERTISLAM_CHECK(robot >= 0 && robot < partition.num_robots());
    CERTISLAM_CHECK(X.cols() == Q.cols() && Q.rows() == Q.cols());
    CertificateRows rows;
    rows.robot = robot;
    rows.d = d;
    rows.first_pose = partition.begin[robot];
    rows.poses = partition.size(robot);
    const int b = d + 1;
    const int c0 = b * rows.first_pose;
    const int cols = b * rows.poses;
    std::map<int, int> nbr;  // neighbour global pose -> compact index
    std::vector<bool> is_public(rows.poses, false);
    Eigen::MatrixXd XQ = Eigen::MatrixXd::Zero(X.rows(), cols);  // (X Q)[:, own columns]
    for (int c = 0; c < cols; ++c) {
        for (Eigen::SparseMatrix<double>::InnerIterator it(Q, c0 + c); it; ++it) {
            const int row = static_cast<int>(it.row());
            XQ.col(c) += it.value() * X.col(row);
            if (row < c0 || row >= c0 + cols) {
                nbr.emplace(row / b, 0);
                is_public[c / b] = true;
            }
        }
    }
    for (auto& [pose, index] : nbr) {
        index = static_cast<int>(rows.neighbor_poses.size());
        rows.neighbor_poses.push_back(pose);
    }
    for (int k = 0; k < rows.poses; ++k) {
        if (is_public[k]) rows.public_poses.push_back(rows.first_pose + k);
    }
    std::vector<Eigen::Triplet<double>> own, cross;
    for (int c = 0; c < cols; ++c) {  // S symmetric: row c of S is column c0 + c of Q
        for (Eigen::SparseMatrix<double>::InnerIterator it(Q, c0 + c); it; ++it) {
            const int row = static_cast<int>(it.row());
            if (row >= c0 && row < c0 + cols) {
                own.emplace_back(c, row - c0, it.value());
            } else {
                cross.emplace_back(c, nbr[row / b] * b + row % b, it.value());
            }
        }
    }
    for (int i = 0; i < rows.poses; ++i) {
        const int c = b * i;
        const Eigen::MatrixXd P = XQ.middleCols(c, d).transpose() * X.middleCols(c0 + c, d);
        const Eigen::MatrixXd lambda = 0.5 * (P + P.transpose());
        rows.trace_lambda += lambda.trace();
        for (int r = 0; r < d; ++r) {
            for (int s = 0; s < d; ++s) own.emplace_back(c + r, c + s, -lambda(r, s));
        }
    }
    rows.own.resize(cols, cols);
    rows.own.setFromTriplets(own.begin(), own.end());
    rows.nbr.resize(cols, b * static_cast<int>(rows.neighbor_poses.size()));
    rows.nbr.setFromTriplets(cross.begin(), cross.end());
    return rows;
}

Eigen::VectorXd PublicEntries(const CertificateRows& rows, const Eigen::VectorXd& v_own) {
    const int b = rows.d + 1;
    Eigen::VectorXd out(b * static_cast<int>(rows.public_poses.size()));
    for (size_t p = 0; p < rows.public_poses.size(); ++p) {
        out.segment(b * p, b) = v_own.segment(b * (rows.public_poses[p] - rows.first_pose), b);
    }
    return out;
}

Eigen::VectorXd MultiplyRows(const CertificateRows& rows, const Eigen::VectorXd& v_own,
                             const Eigen::VectorXd& v_neighbors) {
    Eigen::VectorXd y = rows.own * v_own;
    if (rows.nbr.cols() > 0) y += rows.nbr * v_neighbors;
    return y;
}

bool MakeLocalProblem(int robot, const std::vector<slam::PoseId>& own_ids,
                      const Eigen::MatrixXd& X_own, const std::vector<slam::LoopClosure>& edges,
                      const std::map<slam::PoseId, Eigen::MatrixXd>& neighbor_blocks,
                      LocalCertificateProblem* out) {
    const int n = static_cast<int>(own_ids.size());
    std::map<slam::PoseId, int> local;
    for (int i = 0; i < n; ++i) local[own_ids[static_cast<size_t>(i)]] = i;
    slam::PoseGraph graph;
    graph.d = 3;
    graph.ids = own_ids;
    for (const auto& e : edges) {
        for (const slam::PoseId& id : {e.a, e.b}) {
            if (local.count(id)) continue;
            if (!neighbor_blocks.count(id)) return false;
            local[id] = static_cast<int>(graph.ids.size());
            graph.ids.push_back(id);
        }
        graph.edges.push_back(slam::MeasurementOf(e, local.at(e.a), local.at(e.b)));
    }
    graph.n = static_cast<int>(graph.ids.size());
    Eigen::MatrixXd X(X_own.rows(), kBlock * graph.n);
    X.leftCols(X_own.cols()) = X_own;
    for (int g = n; g < graph.n; ++g) {
        X.middleCols(kBlock * g, kBlock) = neighbor_blocks.at(graph.ids[static_cast<size_t>(g)]);
    }
    // Only Q's own columns are read below: they hold exactly the edges at own poses.
    const Eigen::SparseMatrix<double> Q = slam::ConnectionLaplacian(graph);
    slam::Partition partition;
    partition.begin = {0, n, graph.n};
    LocalCertificateProblem p;
    p.robot = robot;
    p.rows = MakeCertificateRows(Q, X, 3, partition, 0);
    for (int g : p.rows.public_poses) p.public_ids.push_back(graph.ids[static_cast<size_t>(g)]);
    Eigen::MatrixXd X_nbr(X.rows(), kBlock * p.rows.neighbor_poses.size());
    for (size_t k = 0; k < p.rows.neighbor_poses.size(); ++k) {
        const slam::PoseId id = graph.ids[static_cast<size_t>(p.rows.neighbor_poses[k])];
        p.neighbor_ids.push_back(id);
        p.neighbor_robots.insert(id.robot);
        X_nbr.middleCols(kBlock * k, kBlock) =
            X.middleCols(kBlock * p.rows.neighbor_poses[k], kBlock);
    }
    const ObjectiveShare share = ObjectiveOfColumns(Q, X, 0, kBlock * n);
    p.cost = share.value;
    // The team adds the robots' shares in doubles: 64 eps of each covers teams of up to 64.
    p.objective_noise = share.noise + 64.0 * kEpsilon * std::abs(share.value);
    p.x_norm_sq = X_own.squaredNorm();
    Eigen::MatrixXd G = p.rows.own * X_own.transpose();  // (S X^T)[own rows, :]
    if (p.rows.nbr.cols() > 0) G += p.rows.nbr * X_nbr.transpose();
    p.gradient_sq = 4.0 * G.squaredNorm();  // grad f = 2 X S (Riemannian at a critical point)
    for (int c = 0; c < kBlock * n; ++c) {
        double sum = 0.0;
        for (Eigen::SparseMatrix<double>::InnerIterator it(Q, c); it; ++it)
            sum += std::abs(it.value());
        p.q_row_sum = std::max(p.q_row_sum, sum);
    }
    *out = std::move(p);
    return true;
}

}  // namespace certislam::certify
