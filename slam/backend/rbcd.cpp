// SolveRbcd: all robots' agents in one process. Each outer iteration updates every colour class
// of the robot graph in turn (or only the class with the largest gradient when greedy), robots of
// one class together; RBCD++ extrapolates (Nesterov) and restarts when the cost would rise.
#include "slam/backend/rbcd.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <vector>

#include "slam/backend/connection_laplacian.h"
#include "slam/backend/rbcd_block.h"
#include "slam/backend/schwarz_preconditioner.h"
#include "slam/backend/sparse_product.h"
#include "slam/backend/stiefel.h"
#include "slam/core/check.h"

namespace certislam::slam {
namespace {

// Consecutive iterations without real decrease. Near the optimum of ill-conditioned graphs
// (parking-garage) the predicted decrease falls below the cost's rounding noise and every trust-
// region step is rejected: each further iteration then costs full CG runs for nothing.
constexpr int kStallIterations = 3;
constexpr double kStallRelDecrease = 1e-15;

class Team {
  public:
    Team(const Eigen::SparseMatrix<double>& Q, int d, const Partition& partition, int rank,
         const RbcdConfig& config, std::vector<std::vector<int>> classes)
        : d_(d), partition_(partition), classes_(std::move(classes)) {
        for (int k = 0; k < partition.num_robots(); ++k) {
            agents_.emplace_back(Q, d, partition, k, rank, config);
        }
    }

    int block_updates = 0;
    int rtr_iterations = 0;

    // Updates robot k's block of X in place.
    void UpdateRobot(int k, double grad_tol, Eigen::MatrixXd* X) {
        RbcdAgent& agent = agents_[k];
        const int b = d_ + 1;
        const auto& nbr = agent.NeighborPoseIds();
        Eigen::MatrixXd blocks(X->rows(), b * static_cast<int>(nbr.size()));
        for (size_t i = 0; i < nbr.size(); ++i) {
            blocks.middleCols(b * i, b) = X->middleCols(b * nbr[i], b);
        }
        agent.SetNeighborPoses(blocks);
        const int c0 = b * partition_.begin[k];
        const int cols = b * partition_.size(k);
        agent.SetBlock(X->middleCols(c0, cols));
        const RbcdAgentStatus s = agent.Update(grad_tol);
        rtr_iterations += s.rtr_iterations;
        ++block_updates;
        X->middleCols(c0, cols) = agent.Block();
    }

    // One RBCD iteration from X: the chosen colour classes, in turn.
    Eigen::MatrixXd Iterate(Eigen::MatrixXd X, const Eigen::MatrixXd& rgrad, double grad_tol,
                            bool greedy) {
        if (!greedy) {
            for (const auto& cls : classes_) {
                for (int k : cls) UpdateRobot(k, grad_tol, &X);
            }
            return X;
        }
        // RBCD greedy rule applied to colour classes: the largest squared gradient norm.
        const int b = d_ + 1;
        size_t best = 0;
        double best_norm = -1.0;
        for (size_t c = 0; c < classes_.size(); ++c) {
            double sq = 0.0;
            for (int k : classes_[c]) {
                sq +=
                    rgrad.middleCols(b * partition_.begin[k], b * partition_.size(k)).squaredNorm();
            }
            if (sq > best_norm) {
                best_norm = sq;
                best = c;
            }
        }
        for (int k : classes_[best]) UpdateRobot(k, grad_tol, &X);
        return X;
    }

  private:
    int d_;
    Partition partition_;
    std::vector<std::vector<int>> classes_;
    std::vector<RbcdAgent> agents_;
};

struct Evaluation {
    double cost = 0.0;
    Eigen::MatrixXd rgrad;
    double grad_norm = 0.0;
};

Evaluation Evaluate(const Eigen::SparseMatrix<double>& Q, const Eigen::MatrixXd& X, int d) {
    Evaluation e;
    const Eigen::MatrixXd XQ = DenseTimesSparse(X, Q);
    e.cost = XQ.cwiseProduct(X).sum();
    e.rgrad = ProjectToTangent(X, 2.0 * XQ, d);
    e.grad_norm = e.rgrad.norm();
    return e;
}

// The distributed finish (RbcdConfig::polish_after_iterations): trust-region steps on the whole
// X. Per truncated-CG iteration each robot computes its own columns of V Q (its neighbours'
// columns of V in, as for RBCD's linear term) and applies its own factor of the Schwarz
// preconditioner (block Jacobi first, overlapping once CG needs many iterations); the inner
// products are sums of one scalar per robot. Run here in one process on the assembled X.
int Polish(const Eigen::SparseMatrix<double>& Q, int d, const Partition& partition,
           const RbcdConfig& config, double grad_tol, Eigen::MatrixXd* X) {
    SchwarzPreconditioner schwarz(Q, d, partition, config.polish_overlap,
                                  config.polish_escalate_after, config.precon_regulariser);
    const Eigen::MatrixXd no_linear_term;
    std::unique_ptr<TranslationElimination> elim;
    if (config.eliminate_translations) {
        elim = std::make_unique<TranslationElimination>(Q, d, /*anchor_gauge=*/true);
        if (!elim->valid()) elim.reset();
    }
    BlockProblem problem{&Q, &no_linear_term, nullptr, d, nullptr, elim.get()};
    problem.schwarz = &schwarz;
    BlockRtrOptions options;
    options.max_iterations = config.polish_max_rtr_iterations;
    options.max_tcg_iterations = config.polish_max_tcg_iterations;
    options.tcg_residual_floor = config.tcg_residual_floor;
    options.grad_tol = grad_tol;
    options.grad_reduction = 0.0;  // only the global tolerance stops it
    return SolveBlockRtr(problem, options, X).iterations;
}

// What RBCD++ keeps between outer iterations: the iterate, the previous one, its cost and
// gradient, and the Nesterov weight gamma.
struct State {
    Eigen::MatrixXd X, X_prev;
    Evaluation eval;
    double gamma = 1.0;
};

// One outer iteration (RBCD++, Alg. 3): extrapolate, then a block update from there; restart
// from X itself when the cost would rise (plain RBCD without acceleration). Returns true when
// the acceleration restarted.
bool Step(const Eigen::SparseMatrix<double>& Q, int d, bool accelerate, bool greedy,
          double local_tol, Team* team, State* s) {
    Eigen::MatrixXd X_new;
    Evaluation eval_new;
    double gamma_new = 1.0;
    if (accelerate) {
        gamma_new = 0.5 * (1.0 + std::sqrt(1.0 + 4.0 * s->gamma * s->gamma));
        const double beta = (s->gamma - 1.0) / gamma_new;
        const Eigen::MatrixXd Y = ProjectToManifold(s->X + beta * (s->X - s->X_prev), d);
        X_new = team->Iterate(Y, s->eval.rgrad, local_tol, greedy);
        eval_new = Evaluate(Q, X_new, d);
    }
    bool restarted = false;
    if (!accelerate || eval_new.cost > s->eval.cost) {  // adaptive restart from X itself
        restarted = accelerate;
        gamma_new = 1.0;
        X_new = team->Iterate(s->X, s->eval.rgrad, local_tol, greedy);
        eval_new = Evaluate(Q, X_new, d);
    }
    s->gamma = gamma_new;
    s->X_prev = std::move(s->X);
    s->X = std::move(X_new);
    s->eval = std::move(eval_new);
    return restarted;
}

// The second stop: f fell by at most rel_cost_decrease_tol * max(1, f) over cost_window
// iterations.
bool CostConverged(const RbcdConfig& config, const std::vector<double>& costs, int iterations) {
    const double cost = costs.back();
    return config.rel_cost_decrease_tol > 0.0 && iterations > config.cost_window &&
           costs[costs.size() - 1 - config.cost_window] - cost <=
               config.rel_cost_decrease_tol * std::max(1.0, std::abs(cost));
}

}  // namespace

RbcdResult SolveRbcd(const PoseGraph& graph, const Partition& partition, const Eigen::MatrixXd& X0,
                     const RbcdConfig& config,
                     const std::function<void(const RbcdProgress&)>& progress) {
    config.Validate();
    const auto start = std::chrono::steady_clock::now();
    auto elapsed = [&] {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    };
    const int d = graph.d;
    CERTISLAM_CHECK(X0.cols() == (d + 1) * graph.n && X0.rows() >= d);
    CERTISLAM_CHECK(partition.begin.back() == graph.n);
    const Eigen::SparseMatrix<double> Q = ConnectionLaplacian(graph);
    Team team(Q, d, partition, static_cast<int>(X0.rows()), config, ColourRobots(graph, partition));
    const bool accelerate = config.acceleration && partition.num_robots() > 1;
    const bool polish = partition.num_robots() > 1 && config.polish_after_iterations > 0;

    RbcdResult result;
    State s{X0, X0, Evaluate(Q, X0, d), 1.0};
    int stalled = 0;
    std::vector<double> costs{s.eval.cost};
    result.status = RbcdResult::Status::kMaxIterations;
    while (true) {
        const double tol = config.rel_grad_tol * std::max(1.0, s.eval.cost);
        if (s.eval.grad_norm <= tol) {
            result.status = RbcdResult::Status::kConverged;
            break;
        }
        if (result.iterations >= config.max_iterations) break;
        if (polish && result.iterations >= config.polish_after_iterations) break;
        if (elapsed() > config.max_seconds) {
            result.status = RbcdResult::Status::kMaxTime;
            break;
        }
        const double cost_before = s.eval.cost;
        const double local_tol = config.local_tol_factor * tol;
        if (Step(Q, d, accelerate, config.greedy, local_tol, &team, &s)) ++result.restarts;
        const double decrease = cost_before - s.eval.cost;
        stalled =
            decrease <= kStallRelDecrease * std::max(1.0, std::abs(cost_before)) ? stalled + 1 : 0;
        ++result.iterations;
        if (progress)
            progress(RbcdProgress{result.iterations, s.eval.cost, s.eval.grad_norm, elapsed()});
        costs.push_back(s.eval.cost);
        if (CostConverged(config, costs, result.iterations)) {
            result.status = RbcdResult::Status::kCostConverged;
            break;
        }
        // One robot: the trust region is deterministic, a flat iteration will repeat itself.
        if (stalled >= (partition.num_robots() == 1 ? 1 : kStallIterations)) {
            result.status = RbcdResult::Status::kStalled;
            break;
        }
    }
    Eigen::MatrixXd X = std::move(s.X);
    Evaluation eval = std::move(s.eval);
    if (polish && result.status != RbcdResult::Status::kConverged &&
        result.status != RbcdResult::Status::kMaxTime) {
        const double tol = config.rel_grad_tol * std::max(1.0, eval.cost);
        result.polish_rtr_iterations = Polish(Q, d, partition, config, tol, &X);
        eval = Evaluate(Q, X, d);
        result.status = eval.grad_norm <= config.rel_grad_tol * std::max(1.0, eval.cost)
                            ? RbcdResult::Status::kConverged
                            : RbcdResult::Status::kStalled;
        if (progress)
            progress(RbcdProgress{result.iterations, eval.cost, eval.grad_norm, elapsed()});
    }
    result.X = std::move(X);
    result.cost = eval.cost;
    result.grad_norm = eval.grad_norm;
    result.block_updates = team.block_updates;
    result.rtr_iterations = team.rtr_iterations;
    result.seconds = elapsed();
    return result;
}

}  // namespace certislam::slam
