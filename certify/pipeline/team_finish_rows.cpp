// FinishRows: the own rows of S and of Q, and the products the finish takes with them; the
// finish's settings (TeamFinishConfig::Validate).
#include "certify/pipeline/team_finish_rows.h"

#include "certify/pipeline/team_finish.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>

#include "slam/backend/connection_laplacian.h"
#include "slam/backend/stiefel.h"
#include "slam/core/pose_graph.h"

namespace certislam::certify {
namespace {

constexpr int kBlock = 4;  // d + 1 columns per pose (d = 3)
constexpr int kD = 3;

void Require(bool ok, const char* field, double value, const char* rule) {
    if (!ok) {
        throw std::invalid_argument(std::string("TeamFinishConfig.") + field + " = " +
                                    std::to_string(value) + ": must be " + rule);
    }
}

// Own columns of V S from the own block of V and the neighbours' entries.
Eigen::MatrixXd TimesS(const FinishPoint& p, const Eigen::MatrixXd& V_own,
                       const Eigen::MatrixXd& V_nbr) {
    Eigen::MatrixXd SV = p.problem.rows.own * V_own.transpose();
    if (p.problem.rows.nbr.cols() > 0) SV += p.problem.rows.nbr * V_nbr.transpose();
    return SV.transpose();
}

}  // namespace

void TeamFinishConfig::Validate() const {
    Require(rel_grad_tol > 0.0, "rel_grad_tol", rel_grad_tol, "> 0");
    Require(floor_rel_grad_tol >= rel_grad_tol, "floor_rel_grad_tol", floor_rel_grad_tol,
            ">= rel_grad_tol");
    Require(max_iterations >= 1, "max_iterations", max_iterations, ">= 1");
    Require(max_tcg_iterations >= 1, "max_tcg_iterations", max_tcg_iterations, ">= 1");
    Require(tcg_residual_floor >= 0.0 && tcg_residual_floor < 1.0, "tcg_residual_floor",
            tcg_residual_floor, "in [0, 1)");
    Require(overlap >= 0 && overlap <= 8, "overlap", overlap, "in [0, 8]");
    Require(regulariser > 0.0, "regulariser", regulariser, "> 0");
}

Eigen::MatrixXd OwnColumns(const Eigen::MatrixXd& own, const std::vector<slam::PoseId>& ids) {
    Eigen::MatrixXd out(own.rows(), kBlock * Eigen::Index(ids.size()));
    for (size_t k = 0; k < ids.size(); ++k) {
        out.middleCols(kBlock * Eigen::Index(k), kBlock) =
            own.middleCols(kBlock * Eigen::Index(ids[k].index), kBlock);
    }
    return out;
}

PoseBlocks BlocksOf(const std::map<slam::PoseId, Eigen::MatrixXd>& by_id, Eigen::Index rank) {
    PoseBlocks out;
    out.blocks = Eigen::MatrixXd(rank, kBlock * Eigen::Index(by_id.size()));
    for (const auto& [id, block] : by_id) {
        out.blocks.middleCols(kBlock * Eigen::Index(out.ids.size()), kBlock) = block;
        out.ids.push_back(id);
    }
    return out;
}

void StoreEntries(const FinishEntries& in, std::map<slam::PoseId, Eigen::MatrixXd>* by_id) {
    for (const auto& [j, msg] : in) {
        for (size_t k = 0; k < msg.first.size(); ++k) {
            (*by_id)[msg.first[k]] = msg.second.middleCols(kBlock * Eigen::Index(k), kBlock);
        }
    }
}

double SteihaugToBoundary(double e_Pe, double e_Pd, double d_Pd, double radius) {
    if (d_Pd <= 0.0) return 0.0;
    const double disc = std::max(e_Pd * e_Pd + d_Pd * (radius * radius - e_Pe), 0.0);
    return (-e_Pd + std::sqrt(disc)) / d_Pd;
}

std::map<int, std::vector<slam::PoseId>> FinishRows::ReadBy() const {
    std::map<int, std::set<slam::PoseId>> by;
    for (const auto& e : edges_) {
        for (const auto& [p, q] : {std::pair{e.a, e.b}, std::pair{e.b, e.a}}) {
            if (p.robot == robot_ && q.robot != robot_) by[q.robot].insert(p);
        }
    }
    std::map<int, std::vector<slam::PoseId>> out;
    for (const auto& [j, ids] : by) out[j].assign(ids.begin(), ids.end());
    return out;
}

FinishRows::FinishRows(int robot, int n_own, std::vector<slam::LoopClosure> edges)
    : robot_(robot), edges_(std::move(edges)) {
    std::map<slam::PoseId, int> local;
    for (int i = 0; i < n_own; ++i) {
        own_ids_.push_back({robot, i});
        local[own_ids_.back()] = i;
    }
    slam::PoseGraph graph;
    graph.d = kD;
    graph.ids = own_ids_;
    for (const auto& e : edges_) {
        for (const auto& id : {e.a, e.b}) {
            if (local.emplace(id, int(graph.ids.size())).second) {
                graph.ids.push_back(id);
                local_nbr_.push_back(id);
            }
        }
        graph.edges.push_back(slam::MeasurementOf(e, local.at(e.a), local.at(e.b)));
    }
    graph.n = int(graph.ids.size());
    q_cols_ = slam::ConnectionLaplacian(graph).leftCols(kBlock * Eigen::Index(n_own));
}

bool FinishRows::Build(FinishPoint* p) const {
    if (!MakeLocalProblem(robot_, own_ids_, p->X, edges_, p->nbr, &p->problem)) return false;
    Eigen::MatrixXd X_nbr;
    if (!Gather(*p, p->nbr, &X_nbr)) return false;
    p->grad = slam::ProjectToTangent(p->X, 2.0 * TimesS(*p, p->X, X_nbr), kD);
    return true;
}

bool FinishRows::Gather(const FinishPoint& p, const std::map<slam::PoseId, Eigen::MatrixXd>& by_id,
                        Eigen::MatrixXd* out) {
    const auto& ids = p.problem.neighbor_ids;
    *out = Eigen::MatrixXd(p.X.rows(), kBlock * Eigen::Index(ids.size()));
    for (size_t k = 0; k < ids.size(); ++k) {
        const auto it = by_id.find(ids[k]);
        if (it == by_id.end() || it->second.rows() != p.X.rows() || it->second.cols() != kBlock)
            return false;
        out->middleCols(kBlock * Eigen::Index(k), kBlock) = it->second;
    }
    return true;
}

Eigen::MatrixXd FinishRows::Hessian(const FinishPoint& p, const Eigen::MatrixXd& V_own,
                                    const Eigen::MatrixXd& V_nbr) {
    return slam::ProjectToTangent(p.X, 2.0 * TimesS(p, V_own, V_nbr), kD);
}

std::pair<double, double> FinishRows::CostChange(const FinishPoint& at,
                                                 const FinishPoint& cand) const {
    Eigen::MatrixXd V(at.X.rows(), q_cols_.rows());
    V.leftCols(at.X.cols()) = at.X + cand.X;
    for (size_t k = 0; k < local_nbr_.size(); ++k) {
        const auto a = at.nbr.find(local_nbr_[k]);
        const auto b = cand.nbr.find(local_nbr_[k]);
        if (a == at.nbr.end() || b == cand.nbr.end()) return {0.0, 0.0};
        V.middleCols(at.X.cols() + kBlock * Eigen::Index(k), kBlock) = a->second + b->second;
    }
    const Eigen::MatrixXd D = cand.X - at.X;
    const Eigen::MatrixXd VQ = V * q_cols_;
    const Eigen::MatrixXd bound = V.cwiseAbs() * q_cols_.cwiseAbs();
    return {D.cwiseProduct(VQ).sum(),
            8.0 * std::numeric_limits<double>::epsilon() * D.cwiseAbs().cwiseProduct(bound).sum()};
}

}  // namespace certislam::certify
