// The overlapping additive Schwarz preconditioner of the multi-robot finish
// (schwarz_preconditioner.h).
#include "slam/backend/schwarz_preconditioner.h"

#include <algorithm>
#include <utility>

#include "slam/core/check.h"

namespace certislam::slam {
namespace {

// Poses joined by a nonzero block of Q (pose graph adjacency), per pose.
std::vector<std::vector<int>> PoseAdjacency(const Eigen::SparseMatrix<double>& Q, int b) {
    std::vector<std::vector<int>> adj(Q.cols() / b);
    for (int c = 0; c < Q.outerSize(); ++c) {
        for (Eigen::SparseMatrix<double>::InnerIterator it(Q, c); it; ++it) {
            const int j = static_cast<int>(it.row()) / b;
            if (j != c / b) adj[c / b].push_back(j);
        }
    }
    for (auto& a : adj) {
        std::sort(a.begin(), a.end());
        a.erase(std::unique(a.begin(), a.end()), a.end());
    }
    return adj;
}

// Robot k's poses and every pose within `overlap` edges of them, ascending.
std::vector<int> ExtendedDomain(const std::vector<std::vector<int>>& adj,
                                const Partition& partition, int k, int overlap) {
    std::vector<char> in(adj.size(), 0);
    std::vector<int> frontier;
    for (int i = partition.begin[k]; i < partition.begin[k + 1]; ++i) {
        in[i] = 1;
        frontier.push_back(i);
    }
    for (int level = 0; level < overlap && !frontier.empty(); ++level) {
        std::vector<int> next;
        for (int i : frontier) {
            for (int j : adj[i]) {
                if (!in[j]) {
                    in[j] = 1;
                    next.push_back(j);
                }
            }
        }
        frontier = std::move(next);
    }
    std::vector<int> domain;
    for (size_t i = 0; i < in.size(); ++i) {
        if (in[i]) domain.push_back(static_cast<int>(i));
    }
    return domain;
}

// R Q_s R^T for the poses of `domain` (blocks of b entries), shift on the diagonal.
Eigen::SparseMatrix<double> Restrict(const Eigen::SparseMatrix<double>& Q, int b,
                                     const std::vector<int>& domain, double shift) {
    std::vector<int> local(Q.cols() / b, -1);
    for (size_t i = 0; i < domain.size(); ++i) local[domain[i]] = static_cast<int>(i);
    const int m = b * static_cast<int>(domain.size());
    std::vector<Eigen::Triplet<double>> triplets;
    triplets.reserve(static_cast<size_t>(m) * b * 4);
    for (int li = 0; li < static_cast<int>(domain.size()); ++li) {
        for (int a = 0; a < b; ++a) {
            const int c = b * domain[li] + a;
            for (Eigen::SparseMatrix<double>::InnerIterator it(Q, c); it; ++it) {
                const int row = static_cast<int>(it.row());
                const int lj = local[row / b];
                if (lj >= 0) triplets.emplace_back(b * lj + row % b, b * li + a, it.value());
            }
            triplets.emplace_back(b * li + a, b * li + a, shift);
        }
    }
    Eigen::SparseMatrix<double> A(m, m);
    A.setFromTriplets(triplets.begin(), triplets.end());
    return A;
}

}  // namespace

SchwarzPreconditioner::SchwarzPreconditioner(const Eigen::SparseMatrix<double>& Q, int d,
                                             const Partition& partition, int max_overlap,
                                             int escalate_after, double regulariser)
    : Q_(&Q),
      d_(d),
      partition_(partition),
      max_overlap_(max_overlap),
      escalate_after_(escalate_after) {
    CERTISLAM_CHECK(Q.cols() == (d + 1) * partition.begin.back() && max_overlap >= 0 &&
                    escalate_after > 0 && regulariser > 0.0);
    for (int k = 0; k < partition.num_robots(); ++k) CERTISLAM_CHECK(partition.size(k) > 0);
    const double max_diag = Q.diagonal().maxCoeff();
    shift_ = regulariser * (max_diag > 0.0 ? max_diag : 1.0);
    CERTISLAM_CHECK(Build(0));  // blocks of Q_s = Q + shift I are positive definite
}

bool SchwarzPreconditioner::Build(int overlap) {
    const int b = d_ + 1;
    std::vector<std::vector<int>> adj(partition_.begin.back());
    if (overlap > 0) adj = PoseAdjacency(*Q_, b);
    std::vector<std::vector<int>> domains;
    std::vector<std::unique_ptr<BlockFactor>> factors;
    for (int k = 0; k < partition_.num_robots(); ++k) {
        domains.push_back(ExtendedDomain(adj, partition_, k, overlap));
        factors.push_back(std::make_unique<BlockFactor>());
        factors.back()->setMode(Eigen::CholmodSimplicialLLt);
        factors.back()->compute(Restrict(*Q_, b, domains.back(), shift_));
        if (factors.back()->info() != Eigen::Success) return false;
    }
    domains_ = std::move(domains);
    factors_ = std::move(factors);
    overlap_ = overlap;
    return true;
}

int SchwarzPreconditioner::IterationCap(int cap) const {
    return overlap_ < max_overlap_ ? std::min(cap, escalate_after_ + 1) : cap;
}

void SchwarzPreconditioner::ReportCgIterations(int iterations) {
    if (iterations > escalate_after_ && overlap_ < max_overlap_) Build(max_overlap_);
}

Eigen::MatrixXd SchwarzPreconditioner::Solve(const Eigen::MatrixXd& B) const {
    CERTISLAM_CHECK(B.rows() == Q_->rows());
    const int b = d_ + 1;
    Eigen::MatrixXd Z = Eigen::MatrixXd::Zero(B.rows(), B.cols());
    for (size_t k = 0; k < domains_.size(); ++k) {
        const auto& domain = domains_[k];
        Eigen::MatrixXd local(b * domain.size(), B.cols());
        for (size_t i = 0; i < domain.size(); ++i) {
            local.middleRows(b * i, b) = B.middleRows(b * domain[i], b);
        }
        const Eigen::MatrixXd solved = factors_[k]->solve(local);
        for (size_t i = 0; i < domain.size(); ++i) {
            Z.middleRows(b * domain[i], b) += solved.middleRows(b * i, b);
        }
    }
    return Z;
}

}  // namespace certislam::slam
