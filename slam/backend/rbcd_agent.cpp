// The RBCD settings, the lifted cost and gradient, and the per-robot RbcdAgent (Tian et al.,
// T-RO 2021, Alg. 1, line 4: a few preconditioned trust-region steps on one robot's block).
#include "slam/backend/rbcd_agent.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <stdexcept>
#include <string>

#include "slam/backend/connection_laplacian.h"
#include "slam/backend/rbcd_block.h"
#include "slam/backend/sparse_product.h"
#include "slam/backend/stiefel.h"
#include "slam/core/check.h"

namespace certislam::slam {
namespace {

void Require(bool ok, const std::string& field, double value, const std::string& rule) {
    if (!ok) {
        throw std::invalid_argument("RbcdConfig." + field + " = " + std::to_string(value) + ": " +
                                    rule);
    }
}

}  // namespace

void RbcdConfig::Validate() const {
    Require(rel_grad_tol > 0.0, "rel_grad_tol", rel_grad_tol, "must be > 0");
    Require(local_tol_factor > 0.0 && local_tol_factor <= 1.0, "local_tol_factor", local_tol_factor,
            "must be in (0, 1]");
    Require(block_grad_reduction > 0.0 && block_grad_reduction < 1.0, "block_grad_reduction",
            block_grad_reduction, "must be in (0, 1)");
    Require(block_max_rtr_iterations >= 1, "block_max_rtr_iterations", block_max_rtr_iterations,
            "must be >= 1");
    Require(max_tcg_iterations >= 1, "max_tcg_iterations", max_tcg_iterations, "must be >= 1");
    Require(max_iterations >= 1, "max_iterations", max_iterations, "must be >= 1");
    Require(max_seconds > 0.0, "max_seconds", max_seconds, "must be > 0");
    Require(rel_cost_decrease_tol >= 0.0, "rel_cost_decrease_tol", rel_cost_decrease_tol,
            "must be >= 0");
    Require(cost_window >= 1, "cost_window", cost_window, "must be >= 1");
    Require(precon_regulariser > 0.0, "precon_regulariser", precon_regulariser, "must be > 0");
    Require(polish_after_iterations >= 0, "polish_after_iterations", polish_after_iterations,
            "must be >= 0");
    Require(polish_overlap >= 0 && polish_overlap <= 8, "polish_overlap", polish_overlap,
            "must be in [0, 8]");
    Require(polish_escalate_after >= 1, "polish_escalate_after", polish_escalate_after,
            "must be >= 1");
    Require(polish_max_rtr_iterations >= 1, "polish_max_rtr_iterations", polish_max_rtr_iterations,
            "must be >= 1");
    Require(tcg_residual_floor >= 0.0 && tcg_residual_floor < 1.0, "tcg_residual_floor",
            tcg_residual_floor, "must be in [0, 1)");
    Require(polish_max_tcg_iterations >= 1, "polish_max_tcg_iterations", polish_max_tcg_iterations,
            "must be >= 1");
}

double LiftedCost(const Eigen::SparseMatrix<double>& Q, const Eigen::MatrixXd& X) {
    return DenseTimesSparse(X, Q).cwiseProduct(X).sum();
}

Eigen::MatrixXd RiemannianGradient(const Eigen::SparseMatrix<double>& Q, const Eigen::MatrixXd& X,
                                   int d) {
    const Eigen::MatrixXd egrad = 2.0 * DenseTimesSparse(X, Q);
    return ProjectToTangent(X, egrad, d);
}

struct RbcdAgent::Impl {
    int robot = 0;
    int d = 3;
    int rank = 3;
    RbcdConfig config;
    Eigen::SparseMatrix<double> Qaa;  // own block of Q
    Eigen::SparseMatrix<double> Qna;  // rows: neighbour poses' columns (compacted); cols: own
    BlockFactor factor;
    std::unique_ptr<HessianPreconditioner> hessian;  // borrows Qaa (stable: Impl is on the heap)
    std::unique_ptr<TranslationElimination> elim;    // its own copy of Qaa's T columns
    std::vector<int> neighbor_ids;
    std::vector<int> public_ids;
    std::vector<int> public_local;  // local pose index of each public pose
    Eigen::MatrixXd X;              // own block
    Eigen::MatrixXd G;              // linear term X_nbr Q_na

    BlockProblem Problem() const {
        return BlockProblem{&Qaa, &G, &factor, d, hessian.get(), elim.get()};
    }
};

RbcdAgent::RbcdAgent(const PoseGraph& graph, const Partition& partition, int robot, int rank,
                     const RbcdConfig& config) {
    PoseGraph local;
    local.d = graph.d;
    local.n = graph.n;
    const int lo = partition.begin[robot];
    const int hi = partition.begin[robot + 1];
    for (const auto& e : graph.edges) {
        if ((e.i >= lo && e.i < hi) || (e.j >= lo && e.j < hi)) local.edges.push_back(e);
    }
    *this = RbcdAgent(ConnectionLaplacian(local), graph.d, partition, robot, rank, config);
}

RbcdAgent::RbcdAgent(const Eigen::SparseMatrix<double>& Q, int d, const Partition& partition,
                     int robot, int rank, const RbcdConfig& config)
    : impl_(std::make_unique<Impl>()) {
    config.Validate();
    CERTISLAM_CHECK(robot >= 0 && robot < partition.num_robots() && rank >= d);
    Impl& m = *impl_;
    m.robot = robot;
    m.d = d;
    m.rank = rank;
    m.config = config;
    const int b = d + 1;
    const int c0 = b * partition.begin[robot];
    const int cols = b * partition.size(robot);
    // Neighbour poses: rows of Q outside the own range in the own columns.
    std::map<int, int> nbr;  // global pose -> compact index
    std::vector<bool> is_public(partition.size(robot), false);
    for (int c = 0; c < cols; ++c) {
        for (Eigen::SparseMatrix<double>::InnerIterator it(Q, c0 + c); it; ++it) {
            const int row = static_cast<int>(it.row());
            if (row < c0 || row >= c0 + cols) {
                nbr.emplace(row / b, 0);
                is_public[c / b] = true;
            }
        }
    }
    for (auto& [pose, index] : nbr) {
        index = static_cast<int>(m.neighbor_ids.size());
        m.neighbor_ids.push_back(pose);
    }
    for (int k = 0; k < partition.size(robot); ++k) {
        if (is_public[k]) {
            m.public_local.push_back(k);
            m.public_ids.push_back(partition.begin[robot] + k);
        }
    }
    std::vector<Eigen::Triplet<double>> own, cross;
    double max_diag = 0.0;
    for (int c = 0; c < cols; ++c) {
        for (Eigen::SparseMatrix<double>::InnerIterator it(Q, c0 + c); it; ++it) {
            const int row = static_cast<int>(it.row());
            if (row >= c0 && row < c0 + cols) {
                own.emplace_back(row - c0, c, it.value());
                if (row - c0 == c) max_diag = std::max(max_diag, it.value());
            } else {
                cross.emplace_back(nbr[row / b] * b + row % b, c, it.value());
            }
        }
    }
    m.Qaa.resize(cols, cols);
    m.Qaa.setFromTriplets(own.begin(), own.end());
    m.Qna.resize(b * static_cast<int>(m.neighbor_ids.size()), cols);
    m.Qna.setFromTriplets(cross.begin(), cross.end());
    Eigen::SparseMatrix<double> M = m.Qaa;
    for (int c = 0; c < cols; ++c)
        M.coeffRef(c, c) += config.precon_regulariser * (max_diag > 0.0 ? max_diag : 1.0);
    m.factor.setMode(Eigen::CholmodSimplicialLLt);
    m.factor.compute(M);
    if (m.factor.info() != Eigen::Success) {  // input, not a bug: say so instead of aborting
        throw std::invalid_argument(
            "RBCD: robot " + std::to_string(robot) +
            "'s block of the connection Laplacian is not positive definite (rotations not "
            "orthonormal, or non-finite or absurd weights)");
    }
    if (config.hessian_preconditioner)
        m.hessian = std::make_unique<HessianPreconditioner>(m.Qaa, d);
    if (config.eliminate_translations) {
        m.elim = std::make_unique<TranslationElimination>(m.Qaa, d, m.Qna.nonZeros() == 0);
        if (!m.elim->valid()) m.elim.reset();  // Q_TT singular beyond the gauge: explicit
    }
    m.X = Eigen::MatrixXd::Zero(rank, cols);
    m.G = Eigen::MatrixXd::Zero(rank, cols);
}

RbcdAgent::~RbcdAgent() = default;
RbcdAgent::RbcdAgent(RbcdAgent&&) noexcept = default;
RbcdAgent& RbcdAgent::operator=(RbcdAgent&&) noexcept = default;

int RbcdAgent::robot() const { return impl_->robot; }
const std::vector<int>& RbcdAgent::NeighborPoseIds() const { return impl_->neighbor_ids; }
const std::vector<int>& RbcdAgent::PublicPoseIds() const { return impl_->public_ids; }
const Eigen::MatrixXd& RbcdAgent::Block() const { return impl_->X; }

void RbcdAgent::SetBlock(const Eigen::MatrixXd& X_a) {
    CERTISLAM_CHECK(X_a.rows() == impl_->X.rows() && X_a.cols() == impl_->X.cols());
    impl_->X = X_a;
}

void RbcdAgent::SetNeighborPoses(const Eigen::MatrixXd& blocks) {
    Impl& m = *impl_;
    CERTISLAM_CHECK(blocks.rows() == m.rank && blocks.cols() == m.Qna.rows());
    if (m.Qna.rows() == 0) {
        m.G.setZero();
        return;
    }
    m.G = blocks * m.Qna;
}

Eigen::MatrixXd RbcdAgent::PublicPoses() const {
    const Impl& m = *impl_;
    const int b = m.d + 1;
    Eigen::MatrixXd out(m.rank, b * static_cast<int>(m.public_local.size()));
    for (size_t k = 0; k < m.public_local.size(); ++k) {
        out.middleCols(b * k, b) = m.X.middleCols(b * m.public_local[k], b);
    }
    return out;
}

double RbcdAgent::BlockGradNorm() const { return slam::BlockGradNorm(impl_->Problem(), impl_->X); }

RbcdAgentStatus RbcdAgent::Update(double grad_tol) {
    Impl& m = *impl_;
    BlockRtrOptions options;
    options.max_iterations = m.config.block_max_rtr_iterations;
    options.max_tcg_iterations = m.config.max_tcg_iterations;
    options.tcg_residual_floor = m.config.tcg_residual_floor;
    options.grad_tol = grad_tol;
    options.grad_reduction = m.config.block_grad_reduction;
    const BlockRtrOutcome o = SolveBlockRtr(m.Problem(), options, &m.X);
    RbcdAgentStatus s;
    s.cost_before = o.cost_before;
    s.cost_after = o.cost_after;
    s.grad_norm_before = o.grad_norm_before;
    s.grad_norm_after = o.grad_norm_after;
    s.rtr_iterations = o.iterations;
    if (o.iterations == 0) {
        s.status = RbcdAgentStatus::Status::kConverged;
    } else if (o.accepted == 0) {
        s.status = RbcdAgentStatus::Status::kNoProgress;
    } else {
        s.status = RbcdAgentStatus::Status::kImproved;
    }
    return s;
}

}  // namespace certislam::slam
