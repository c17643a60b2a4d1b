// The overlapping additive Schwarz preconditioner of the multi-robot finish
// (schwarz_preconditioner.h).
#include "slam/schwarz_preconditioner.h"

#include <algorithm>

#include "slam/check.h"

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
    for (int level = 0; level < overlap; ++level) {
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
    std::vector<Eigen::Triplet<double>> triplets;
    for (size_t li = 0; li < domain.size(); ++li) {
        for (int a = 0; a < b; ++a) {
            const int c = b * domain[li] + a;
            for (Eigen::SparseMatrix<double>::InnerIterator it(Q, c); it; ++it) {
                const int lj = local[it.row() / b];
                if (lj < 0) continue;
                triplets.emplace_back(b * lj + static_cast<int>(it.row()) % b,
                                      b * static_cast<int>(li) + a, it.value());
            }
            triplets.emplace_back(b * li + a, b * li + a, shift);
        }
    }
    const int m = b * static_cast<int>(domain.size());
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
    const double max_diag = Q.diagonal().maxCoeff();
    shift_ = regulariser * (max_diag > 0.0 ? max_diag : 1.0);
    Build(0);
}

void SchwarzPreconditioner::Build(int overlap) {
    const int b = d_ + 1;
    const auto adj = PoseAdjacency(*Q_, b);
    domains_.clear();
    factors_.clear();
    for (int k = 0; k < partition_.num_robots(); ++k) {
        domains_.push_back(ExtendedDomain(adj, partition_, k, overlap));
        factors_.push_back(std::make_unique<BlockFactor>());
        factors_.back()->setMode(Eigen::CholmodSimplicialLLt);
        factors_.back()->compute(Restrict(*Q_, b, domains_.back(), shift_));
        CERTISLAM_CHECK(factors_.back()->info() == Eigen::Success);
    }
    overlap_ = overlap;
}

void SchwarzPreconditioner::ReportCgIterations(int iterations) {
    if (iterations > escalate_after_ && overlap_ < max_overlap_) Build(max_overlap_);
}

SchwarzPreconditioner::~SchwarzPreconditioner() = default;

Eigen::MatrixXd SchwarzPreconditioner::Solve(const Eigen::MatrixXd& B) const {
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
