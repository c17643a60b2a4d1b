// Block LOBPCG with a block-Jacobi preconditioner over robots' rows of S, run in memory.
#include "certify/distributed/distributed_lobpcg.h"

#include <Eigen/CholmodSupport>
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>

#include "certify/distributed/lobpcg_rayleigh_ritz.h"
#include "slam/core/check.h"

namespace certislam::certify {
namespace {

using Block = Eigen::MatrixXd;
using Blocks = std::vector<Block>;  ///< one segment (rows of S) per robot
using Factor = Eigen::CholmodDecomposition<Eigen::SparseMatrix<double>, Eigen::Lower>;

constexpr std::uint64_t kRobotSeed = 7919;  ///< start block seed stride per robot
constexpr int kMaxShiftAttempts = 40;       ///< factorisations a robot tries at most

/// The robots' rows, their preconditioners and the message counters: every operation that would
/// be a message in the distributed run is counted here.
class Team {
  public:
    Team(const std::vector<CertificateRows>& robots, LobpcgResult* counts)
        : robots_(robots), counts_(counts) {
        std::map<int, std::pair<int, Eigen::Index>> where;  // public pose -> (robot, offset)
        for (size_t k = 0; k < robots.size(); ++k) {
            const int b = robots[k].d + 1;
            for (const int g : robots[k].public_poses) {
                where[g] = {static_cast<int>(k), b * (g - robots[k].first_pose)};
            }
        }
        routes_.resize(robots.size());
        for (size_t k = 0; k < robots.size(); ++k) {
            for (const int g : robots[k].neighbor_poses) {
                const auto it = where.find(g);
                CERTISLAM_CHECK(it != where.end());  // a neighbour pose is public at its owner
                routes_[k].push_back(it->second);
            }
        }
    }

    size_t size() const { return robots_.size(); }
    const CertificateRows& rows(size_t k) const { return robots_[k]; }

    /// S B: one neighbour exchange of the public entries of B's columns.
    Blocks Multiply(const Blocks& B) {
        ++counts_->vector_exchanges;
        counts_->products += static_cast<int>(B.front().cols());
        Blocks out(size());
        for (size_t k = 0; k < size(); ++k) {
            const CertificateRows& r = robots_[k];
            const int b = r.d + 1;
            counts_->entries_exchanged +=
                static_cast<double>(b * r.public_poses.size() * B[k].cols());
            Block nbr(b * static_cast<Eigen::Index>(routes_[k].size()), B[k].cols());
            for (size_t i = 0; i < routes_[k].size(); ++i) {
                const auto& [owner, offset] = routes_[k][i];
                nbr.middleRows(b * static_cast<Eigen::Index>(i), b) =
                    B[owner].middleRows(offset, b);
            }
            out[k] = r.own * B[k];
            if (r.nbr.cols() > 0) out[k] += r.nbr * nbr;
        }
        return out;
    }

    /// The sum over robots, in robot order, of every robot's partial array: one reduction.
    Eigen::VectorXd Reduce(const std::vector<Eigen::VectorXd>& partials) {
        ++counts_->scalar_reductions;
        counts_->scalars_reduced += static_cast<double>(partials.front().size());
        Eigen::VectorXd sum = Eigen::VectorXd::Zero(partials.front().size());
        for (const auto& p : partials) sum += p;
        return sum;
    }

    /// Each robot factorises S_kk + tau I (no message); returns the largest tau used.
    double Factorise(double tau0, double growth) {
        factors_.clear();
        double largest = 0.0;
        for (const auto& r : robots_) {
            auto factor = std::make_unique<Factor>();
            factor->setMode(Eigen::CholmodSimplicialLLt);  // LL^T fails on indefinite blocks
            double tau = tau0;
            for (int attempt = 0; attempt < kMaxShiftAttempts; ++attempt, tau *= growth) {
                Eigen::SparseMatrix<double> A = r.own;
                for (Eigen::Index i = 0; i < A.rows(); ++i) A.coeffRef(i, i) += tau;
                factor->compute(A);
                if (factor->info() == Eigen::Success) break;
            }
            CERTISLAM_CHECK(factor->info() == Eigen::Success);
            largest = std::max(largest, tau);
            factors_.push_back(std::move(factor));
        }
        return largest;
    }

    /// (S_kk + tau I)^{-1} R_k on robot k's segment (no message).
    Block Precondition(size_t k, const Block& R) const { return factors_[k]->solve(R); }

  private:
    const std::vector<CertificateRows>& robots_;
    LobpcgResult* counts_;
    std::vector<std::vector<std::pair<int, Eigen::Index>>> routes_;
    std::vector<std::unique_ptr<Factor>> factors_;
};

/// The upper triangle of M (row by row), appended to `out` from `at`.
void PackUpper(const Block& M, Eigen::VectorXd* out, Eigen::Index* at) {
    for (Eigen::Index i = 0; i < M.rows(); ++i) {
        for (Eigen::Index j = i; j < M.cols(); ++j) (*out)((*at)++) = M(i, j);
    }
}

/// The symmetric s x s matrix whose upper triangle was packed from `from`.
Block UnpackUpper(const Eigen::VectorXd& v, Eigen::Index s, Eigen::Index* from) {
    Block M(s, s);
    for (Eigen::Index i = 0; i < s; ++i) {
        for (Eigen::Index j = i; j < s; ++j) M(i, j) = M(j, i) = v((*from)++);
    }
    return M;
}

/// The iteration's state, segment by robot.
struct State {
    Blocks X, AX, P, AP;
    Eigen::VectorXd theta;     ///< Ritz values of X's columns
    std::vector<bool> active;  ///< columns whose residual is still above tolerance
};

/// Z = [X W P] on robot k, and S Z.
std::pair<Block, Block> Basis(const State& s, const Blocks& W, const Blocks& AW, size_t k) {
    const Eigen::Index n = s.X[k].rows();
    const Eigen::Index p = s.P.empty() ? 0 : s.P[k].cols();
    const Eigen::Index cols = s.X[k].cols() + W[k].cols() + p;
    Block Z(n, cols), AZ(n, cols);
    Z << s.X[k], W[k], (p > 0 ? s.P[k] : Block(n, 0));
    AZ << s.AX[k], AW[k], (p > 0 ? s.AP[k] : Block(n, 0));
    return {Z, AZ};
}

/// One robot's residual block R = S X - X diag(theta).
Block Residual(const State& s, size_t k) { return s.AX[k] - s.X[k] * s.theta.asDiagonal(); }

/// Ritz values and the exact residuals of X (one exchange, one reduction): refreshes S X.
Eigen::VectorXd Verify(Team& team, State* s) {
    s->AX = team.Multiply(s->X);
    const Eigen::Index m = s->X.front().cols();
    std::vector<Eigen::VectorXd> partials;
    for (size_t k = 0; k < team.size(); ++k) {
        Eigen::VectorXd p(3 * m);
        const Block R = Residual(*s, k);
        for (Eigen::Index j = 0; j < m; ++j) {
            p(j) = s->X[k].col(j).squaredNorm();
            p(m + j) = s->X[k].col(j).dot(s->AX[k].col(j));
            p(2 * m + j) = R.col(j).squaredNorm();
        }
        partials.push_back(p);
    }
    return team.Reduce(partials);
}

/// The setup: a random block, its product and Ritz values, and ||S||_inf (one exchange, one
/// reduction carrying the Gram matrices and each robot's largest row sum).
State Start(Team& team, const LobpcgSettings& settings, int m, double* scale) {
    State s;
    for (size_t k = 0; k < team.size(); ++k) {
        std::mt19937_64 rng(settings.seed + kRobotSeed * static_cast<std::uint64_t>(k));
        std::normal_distribution<double> normal;
        Block X(team.rows(k).own.rows(), m);
        for (Eigen::Index i = 0; i < X.size(); ++i) X.data()[i] = normal(rng);
        s.X.push_back(X);
    }
    s.AX = team.Multiply(s.X);
    const Eigen::Index packed = m * (m + 1) / 2;
    std::vector<Eigen::VectorXd> partials;
    double row_sum = 0.0;  // max over robots: in the distributed run, a maximum in this reduction
    for (size_t k = 0; k < team.size(); ++k) {
        const CertificateRows& r = team.rows(k);
        Eigen::VectorXd rows = Eigen::VectorXd::Zero(r.own.rows());
        for (Eigen::Index c = 0; c < r.own.outerSize(); ++c) {
            for (Eigen::SparseMatrix<double>::InnerIterator it(r.own, c); it; ++it) {
                rows(it.row()) += std::abs(it.value());
            }
        }
        for (Eigen::Index c = 0; c < r.nbr.outerSize(); ++c) {
            for (Eigen::SparseMatrix<double>::InnerIterator it(r.nbr, c); it; ++it) {
                rows(it.row()) += std::abs(it.value());
            }
        }
        row_sum = std::max(row_sum, rows.maxCoeff());
        Eigen::VectorXd p(2 * packed);
        Eigen::Index at = 0;
        PackUpper(s.X[k].transpose() * s.X[k], &p, &at);
        PackUpper(s.X[k].transpose() * s.AX[k], &p, &at);
        partials.push_back(p);
    }
    const Eigen::VectorXd sums = team.Reduce(partials);
    *scale = row_sum;
    Eigen::Index from = 0;
    LobpcgGram z;
    z.x = m;
    z.gram = UnpackUpper(sums, m, &from);
    z.s_gram = UnpackUpper(sums, m, &from);
    const RayleighRitzResult rr = SolveRayleighRitz(z, m, settings.drop_tolerance);
    CERTISLAM_CHECK(rr.ok);  // a random block is independent
    for (size_t k = 0; k < team.size(); ++k) {
        s.X[k] = s.X[k] * rr.coefficients;
        s.AX[k] = s.AX[k] * rr.coefficients;
    }
    s.theta = rr.ritz_values;
    s.active.assign(static_cast<size_t>(m), true);
    return s;
}

}  // namespace

namespace {

/// What one iteration's reduction returned: the basis' Gram matrices and X's residual norms.
struct IterationSums {
    LobpcgGram z;
    Eigen::VectorXd residual;  ///< ||S x_j - theta_j x_j|| (recurrence S X)
    Blocks W, AW;              ///< this iteration's preconditioned residuals and their products
};

/// LOBPCG's W = T R on the active columns (no message), S W (one exchange) and the Gram matrices
/// of [X W P] with X's residual norms (one reduction).
IterationSums Exchange(Team& team, const State& s) {
    const Eigen::Index m = s.X.front().cols();
    std::vector<Eigen::Index> active;
    for (Eigen::Index j = 0; j < m; ++j) {
        if (s.active[static_cast<size_t>(j)]) active.push_back(j);
    }
    IterationSums out;
    std::vector<Block> R(team.size());
    for (size_t k = 0; k < team.size(); ++k) {
        R[k] = Residual(s, k);
        out.W.push_back(team.Precondition(k, R[k](Eigen::all, active)));
    }
    out.AW = team.Multiply(out.W);
    out.z.x = static_cast<int>(m);
    out.z.w = static_cast<int>(active.size());
    out.z.p = s.P.empty() ? 0 : static_cast<int>(m);
    const Eigen::Index cols = out.z.x + out.z.w + out.z.p;
    const Eigen::Index packed = cols * (cols + 1) / 2;
    std::vector<Eigen::VectorXd> partials;
    for (size_t k = 0; k < team.size(); ++k) {
        const auto [Z, AZ] = Basis(s, out.W, out.AW, k);
        Eigen::VectorXd p(2 * packed + m);
        Eigen::Index at = 0;
        PackUpper(Z.transpose() * Z, &p, &at);
        PackUpper(Z.transpose() * AZ, &p, &at);
        p.tail(m) = R[k].colwise().squaredNorm().transpose();
        partials.push_back(p);
    }
    const Eigen::VectorXd sums = team.Reduce(partials);
    Eigen::Index from = 0;
    out.z.gram = UnpackUpper(sums, cols, &from);
    out.z.s_gram = UnpackUpper(sums, cols, &from);
    out.residual = sums.tail(m).cwiseSqrt();
    return out;
}

/// The Rayleigh-Ritz update of X and P from the iteration's sums (no message); false when the
/// basis lost independence beyond repair.
bool Update(const IterationSums& it, const LobpcgSettings& settings, State* s, int* restarts) {
    const int m = it.z.x;
    const RayleighRitzResult rr = SolveRayleighRitz(it.z, m, settings.drop_tolerance);
    if (!rr.ok) return false;
    if (rr.dropped_p) ++*restarts;
    const Block& C = rr.coefficients;
    const Block Cx = C.topRows(m), Cw = C.middleRows(m, it.z.w), Cp = C.bottomRows(it.z.p);
    for (size_t k = 0; k < s->X.size(); ++k) {
        Block P = it.W[k] * Cw;
        Block AP = it.AW[k] * Cw;
        if (it.z.p > 0) {
            P += s->P[k] * Cp;
            AP += s->AP[k] * Cp;
        }
        s->X[k] = s->X[k] * Cx + P;
        s->AX[k] = s->AX[k] * Cx + AP;
        if (s->P.size() < s->X.size()) {
            s->P.resize(s->X.size());
            s->AP.resize(s->X.size());
        }
        s->P[k] = std::move(P);
        s->AP[k] = std::move(AP);
    }
    s->theta = rr.ritz_values;
    return true;
}

/// The exact Rayleigh quotient and residual of X's first column into `result`; true when that
/// residual is within `limit`.
bool Confirm(Team& team, State* s, double limit, LobpcgResult* result) {
    const Eigen::Index m = s->X.front().cols();
    const Eigen::VectorXd sums = Verify(team, s);
    const double norm = std::sqrt(sums(0));
    result->lambda_min = sums(m) / sums(0);
    // ||S x - lambda x|| <= ||S x - theta x|| for the Rayleigh quotient lambda.
    result->residual = std::sqrt(sums(2 * m)) / norm;
    result->vector.clear();
    for (const Block& X : s->X) result->vector.push_back(X.col(0) / norm);
    return result->residual <= limit;
}

}  // namespace

void LobpcgSettings::Validate() const {
    const auto fail = [](const std::string& field, double value, const std::string& rule) {
        throw std::invalid_argument("LobpcgSettings." + field + " = " + std::to_string(value) +
                                    ": must be " + rule);
    };
    if (block_size < 1) fail("block_size", block_size, ">= 1");
    if (max_iterations < 1) fail("max_iterations", max_iterations, ">= 1");
    if (!(tolerance > 0.0)) fail("tolerance", tolerance, "> 0");
    if (!(shift_relative > 0.0)) fail("shift_relative", shift_relative, "> 0");
    if (!(shift_growth > 1.0)) fail("shift_growth", shift_growth, "> 1");
    if (!(drop_tolerance > 0.0 && drop_tolerance < 1.0)) {
        fail("drop_tolerance", drop_tolerance, "in (0, 1)");
    }
}

LobpcgResult DistributedLobpcg(const std::vector<CertificateRows>& robots,
                               const LobpcgSettings& settings) {
    settings.Validate();
    CERTISLAM_CHECK(!robots.empty());
    LobpcgResult result;
    Team team(robots, &result);
    Eigen::Index dimension = 0;
    for (const auto& r : robots) dimension += r.own.rows();
    const int m = static_cast<int>(std::min<Eigen::Index>(settings.block_size, dimension / 3));
    CERTISLAM_CHECK(m >= 1);  // [X W P] must fit in the space
    State s = Start(team, settings, m, &result.scale);
    result.max_shift =
        team.Factorise(settings.shift_relative * result.scale, settings.shift_growth);
    const double limit = settings.tolerance * result.scale;
    result.status = LobpcgResult::Status::kNotConverged;
    while (result.iterations < settings.max_iterations) {
        ++result.iterations;
        const IterationSums sums = Exchange(team, s);
        if (sums.residual(0) <= limit && Confirm(team, &s, limit, &result)) {
            result.status = LobpcgResult::Status::kConverged;
            return result;
        }
        for (int j = 1; j < m; ++j) s.active[static_cast<size_t>(j)] = sums.residual(j) > limit;
        if (!Update(sums, settings, &s, &result.restarts)) {
            result.status = LobpcgResult::Status::kBreakdown;
            break;
        }
    }
    Confirm(team, &s, limit, &result);
    return result;
}

}  // namespace certislam::certify
