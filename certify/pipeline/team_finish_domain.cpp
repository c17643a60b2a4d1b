// FinishDomain: the reach of a neighbour's domain into the own poses, and the domain's factor.
#include "certify/pipeline/team_finish_domain.h"

#include <algorithm>
#include <utility>

#include "slam/backend/connection_laplacian.h"
#include "slam/core/pose_graph.h"

namespace certislam::certify {
namespace {

constexpr int kBlock = 4;  // d + 1 columns per pose (d = 3)

}  // namespace

FinishDomain::FinishDomain(int robot, int n_own, const std::vector<slam::LoopClosure>& edges,
                           int overlap, double regulariser)
    : robot_(robot), n_own_(n_own), regulariser_(regulariser) {
    std::map<slam::PoseId, std::vector<slam::PoseId>> own_adjacent;  // own pose -> poses
    std::map<int, std::set<slam::PoseId>> frontier;  // neighbour -> own poses next to it
    for (const auto& e : edges) {
        if (!known_.insert({e.a, e.b}).second) continue;
        edges_.push_back(e);
        for (const auto& [p, q] : {std::pair{e.a, e.b}, std::pair{e.b, e.a}}) {
            if (p.robot != robot) continue;
            own_adjacent[p].push_back(q);
            if (q.robot != robot) frontier[q.robot].insert(p);
        }
    }
    for (auto& [j, reached] : frontier) {
        std::set<slam::PoseId> all = overlap > 0 ? reached : std::set<slam::PoseId>{};
        std::set<slam::PoseId> front = all;
        for (int step = 1; step < overlap && !front.empty(); ++step) {
            std::set<slam::PoseId> grown;
            for (const auto& p : front) {
                for (const auto& q : own_adjacent[p]) {
                    if (q.robot == robot && all.insert(q).second) grown.insert(q);
                }
            }
            front = std::move(grown);
        }
        own_in_[j].assign(all.begin(), all.end());
    }
}

FinishDomain::~FinishDomain() = default;

const std::vector<slam::PoseId>& FinishDomain::OwnPosesIn(int j) const {
    static const std::vector<slam::PoseId> kNone;
    const auto it = own_in_.find(j);
    return it == own_in_.end() ? kNone : it->second;
}

std::vector<slam::LoopClosure> FinishDomain::EdgesFor(int j) const {
    const auto& poses = OwnPosesIn(j);
    const std::set<slam::PoseId> in(poses.begin(), poses.end());
    std::vector<slam::LoopClosure> out;
    for (const auto& e : edges_) {
        if (in.count(e.a) || in.count(e.b)) out.push_back(e);
    }
    return out;
}

void FinishDomain::Add(int j, const std::vector<slam::PoseId>& poses,
                       const std::vector<slam::LoopClosure>& edges) {
    for (const auto& p : poses) {
        if (p.robot == j) added_.insert(p);  // a neighbour speaks for its own poses only
    }
    for (const auto& e : edges) {  // only edges at the sender's poses, each pair once
        if ((e.a.robot == j || e.b.robot == j) && known_.insert({e.a, e.b}).second)
            edges_.push_back(e);
    }
}

bool FinishDomain::Factorize() {
    others_.assign(added_.begin(), added_.end());
    std::map<slam::PoseId, int> local;
    for (int k = 0; k < n_own_; ++k) local[{robot_, k}] = k;
    for (const auto& id : others_) local.emplace(id, static_cast<int>(local.size()));
    const int in_domain = static_cast<int>(local.size());
    slam::PoseGraph graph;
    graph.d = 3;
    for (const auto& e : edges_) {
        if (!local.count(e.a) && !local.count(e.b)) continue;  // an edge a neighbour sent beyond
        for (const auto& id : {e.a, e.b}) local.emplace(id, static_cast<int>(local.size()));
        graph.edges.push_back(slam::MeasurementOf(e, local.at(e.a), local.at(e.b)));
    }
    graph.n = static_cast<int>(local.size());
    graph.ids.resize(local.size());
    for (const auto& [id, k] : local) graph.ids[static_cast<size_t>(k)] = id;
    // Edges leaving the domain add to its diagonal only: a principal submatrix of Q.
    const Eigen::SparseMatrix<double> Q = slam::ConnectionLaplacian(graph);
    const int m = kBlock * in_domain;
    Eigen::SparseMatrix<double> QD = Q.topLeftCorner(m, m);
    double scale = 1.0;
    for (int c = 0; c < m; ++c) scale = std::max(scale, QD.coeff(c, c));
    Eigen::SparseMatrix<double> shift(m, m);
    shift.setIdentity();
    QD += (regulariser_ * scale) * shift;
    factor_ = std::make_unique<slam::BlockFactor>();
    factor_->setMode(Eigen::CholmodSimplicialLLt);
    factor_->cholmod().print = 0;  // a failure is handled (TeamFinish fails the team's finish)
    factor_->compute(QD);
    return factor_->info() == Eigen::Success;
}

Eigen::MatrixXd FinishDomain::Solve(const Eigen::MatrixXd& B) const {
    // Column-major right-hand side: Eigen's sparse triangular solves are slow on row-major ones.
    const Eigen::MatrixXd Bt = B.transpose();
    return factor_->solve(Bt).transpose();
}

bool FinishDomain::Solve(const Eigen::MatrixXd& r,
                         const std::map<slam::PoseId, Eigen::MatrixXd>& by_id,
                         Eigen::MatrixXd* z_own, std::map<int, std::vector<slam::PoseId>>* ids,
                         std::map<int, Eigen::MatrixXd>* blocks, double* rz) const {
    Eigen::MatrixXd rD(r.rows(), r.cols() + kBlock * Eigen::Index(others_.size()));
    rD.leftCols(r.cols()) = r;
    for (size_t k = 0; k < others_.size(); ++k) {
        const auto it = by_id.find(others_[k]);
        if (it == by_id.end() || it->second.rows() != r.rows() || it->second.cols() != kBlock)
            return false;
        rD.middleCols(r.cols() + kBlock * Eigen::Index(k), kBlock) = it->second;
    }
    const Eigen::MatrixXd zD = Solve(rD);
    *rz = rD.cwiseProduct(zD).sum();
    *z_own = zD.leftCols(r.cols());
    std::map<int, std::vector<Eigen::Index>> at;  // neighbour -> columns of zD
    for (size_t k = 0; k < others_.size(); ++k) {
        (*ids)[others_[k].robot].push_back(others_[k]);
        at[others_[k].robot].push_back(r.cols() + kBlock * Eigen::Index(k));
    }
    for (auto& [j, list] : *ids) {
        Eigen::MatrixXd& b = (*blocks)[j];
        b.resize(r.rows(), kBlock * Eigen::Index(list.size()));
        for (size_t k = 0; k < list.size(); ++k)
            b.middleCols(kBlock * Eigen::Index(k), kBlock) = zD.middleCols(at[j][k], kBlock);
    }
    return true;
}

bool FinishDomain::AddReturned(
    const std::map<int, std::pair<std::vector<slam::PoseId>, Eigen::MatrixXd>>& in,
    Eigen::MatrixXd* z) const {
    for (const auto& [j, msg] : in) {
        if (msg.second.rows() != z->rows()) return false;
        for (size_t k = 0; k < msg.first.size(); ++k) {
            const slam::PoseId& id = msg.first[k];
            if (id.robot != robot_ || id.index < 0 || id.index >= n_own_) return false;
            z->middleCols(kBlock * id.index, kBlock) +=
                msg.second.middleCols(kBlock * Eigen::Index(k), kBlock);
        }
    }
    return true;
}

}  // namespace certislam::certify
