// Overlapping block update: one RbcdAgent on [own | overlap] against the fixed poses beyond.
#include "certify/pipeline/overlap_sweep.h"

#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>

namespace certislam::certify {
namespace {

constexpr int kBlock = 4;  // d + 1 columns per pose (d = 3)

using Adjacency = std::map<slam::PoseId, std::vector<slam::PoseId>>;

/// Poses within `depth` edges of `sources`, walking only through poses `pass` accepts.
template <typename Pass>
std::set<slam::PoseId> Reach(const Adjacency& adjacent, const std::set<slam::PoseId>& sources,
                             int depth, Pass pass) {
    std::set<slam::PoseId> out, frontier = sources;
    for (int step = 0; step < depth && !frontier.empty(); ++step) {
        std::set<slam::PoseId> grown;
        for (const auto& id : frontier) {
            const auto it = adjacent.find(id);
            if (it == adjacent.end()) continue;
            for (const auto& j : it->second) {
                if (pass(j) && out.insert(j).second) grown.insert(j);
            }
        }
        frontier = std::move(grown);
    }
    return out;
}

}  // namespace

struct OverlapSweep::Impl {
    int n_own = 0;
    std::vector<slam::PoseId> overlap;  ///< domain's other poses, local n_own + k
    std::vector<slam::PoseId> fixed;    ///< beyond the domain, local n_own + |overlap| + k
    std::optional<slam::RbcdAgent> agent;
    PoseBlocks proposals;
    double grad_norm = 0.0;
};

OverlapSweep::OverlapSweep(int robot, int n_own, int rank,
                           const std::vector<slam::LoopClosure>& edges,
                           const std::set<slam::PoseId>& overlap, const slam::RbcdConfig& config)
    : impl_(std::make_unique<Impl>()) {
    Impl& m = *impl_;
    m.n_own = n_own;
    m.overlap.assign(overlap.begin(), overlap.end());
    if (m.overlap.empty()) return;  // nothing to sweep beyond the own block: no second solver
    std::map<slam::PoseId, int> local;
    for (int k = 0; k < n_own; ++k) local[{robot, k}] = k;
    for (const auto& id : m.overlap) local.emplace(id, static_cast<int>(local.size()));
    std::vector<const slam::LoopClosure*> domain_edges;
    std::set<slam::PoseId> beyond;
    for (const auto& e : edges) {
        if (!local.count(e.a) && !local.count(e.b)) continue;
        domain_edges.push_back(&e);
        for (const auto& id : {e.a, e.b}) {
            if (!local.count(id)) beyond.insert(id);
        }
    }
    m.fixed.assign(beyond.begin(), beyond.end());
    for (const auto& id : m.fixed) local.emplace(id, static_cast<int>(local.size()));
    slam::PoseGraph graph;
    graph.d = 3;
    graph.n = static_cast<int>(local.size());
    graph.ids.resize(local.size());
    for (const auto& [id, k] : local) graph.ids[k] = id;
    for (const auto* e : domain_edges) {
        graph.edges.push_back(slam::MeasurementOf(*e, local.at(e->a), local.at(e->b)));
    }
    const int free = n_own + static_cast<int>(m.overlap.size());
    slam::Partition partition{{0, free}};
    if (graph.n > free) partition.begin.push_back(graph.n);
    m.agent.emplace(graph, partition, 0, rank, config);
}
OverlapSweep::~OverlapSweep() = default;
OverlapSweep::OverlapSweep(OverlapSweep&&) noexcept = default;
OverlapSweep& OverlapSweep::operator=(OverlapSweep&&) noexcept = default;

Eigen::MatrixXd OverlapSweep::Sweep(const Eigen::MatrixXd& X_own, const PoseBlocks& others,
                                    double grad_tol) {
    Impl& m = *impl_;
    if (!m.agent) throw std::invalid_argument("OverlapSweep: the domain has no overlap");
    if (X_own.cols() != kBlock * Eigen::Index(m.n_own)) {
        throw std::invalid_argument("OverlapSweep: the own block has " +
                                    std::to_string(X_own.cols() / kBlock) + " poses, not " +
                                    std::to_string(m.n_own));
    }
    std::map<slam::PoseId, Eigen::Index> at;
    for (size_t k = 0; k < others.ids.size(); ++k) at[others.ids[k]] = Eigen::Index(k);
    const auto pose = [&](const slam::PoseId& id) -> Eigen::MatrixXd {
        const auto it = at.find(id);
        if (it == at.end() || others.blocks.rows() < X_own.rows()) {
            throw std::invalid_argument("OverlapSweep: pose " + std::to_string(id.robot) + "/" +
                                        std::to_string(id.index) + " of the domain is not known");
        }
        return others.blocks.middleCols(kBlock * it->second, kBlock).topRows(X_own.rows());
    };
    const Eigen::Index own_cols = X_own.cols();
    Eigen::MatrixXd X(X_own.rows(), own_cols + kBlock * Eigen::Index(m.overlap.size()));
    X.leftCols(own_cols) = X_own;
    for (size_t k = 0; k < m.overlap.size(); ++k)
        X.middleCols(own_cols + kBlock * Eigen::Index(k), kBlock) = pose(m.overlap[k]);
    Eigen::MatrixXd F(X_own.rows(), kBlock * Eigen::Index(m.fixed.size()));
    for (size_t k = 0; k < m.fixed.size(); ++k)
        F.middleCols(kBlock * Eigen::Index(k), kBlock) = pose(m.fixed[k]);
    m.agent->SetBlock(X);
    m.agent->SetNeighborPoses(F);
    const slam::RbcdAgentStatus status = m.agent->Update(grad_tol);
    m.grad_norm = status.rtr_iterations == 0 ? status.grad_norm_before : status.grad_norm_after;
    const Eigen::MatrixXd& out = m.agent->Block();
    m.proposals.ids = m.overlap;
    m.proposals.blocks = out.rightCols(out.cols() - own_cols);
    return out.leftCols(own_cols);
}

const PoseBlocks& OverlapSweep::Proposals() const { return impl_->proposals; }
double OverlapSweep::GradNorm() const { return impl_->grad_norm; }
int OverlapSweep::OverlapSize() const { return static_cast<int>(impl_->overlap.size()); }

std::set<slam::PoseId> OverlapDomain(int robot, const std::vector<slam::LoopClosure>& edges,
                                     int depth, const std::set<int>& later) {
    Adjacency adjacent;
    for (const auto& e : edges) {
        adjacent[e.a].push_back(e.b);
        adjacent[e.b].push_back(e.a);
    }
    std::set<slam::PoseId> own;
    for (const auto& [id, next] : adjacent) {
        if (id.robot == robot) own.insert(id);
    }
    const auto joinable = [&](const slam::PoseId& id) {
        if (!later.count(id.robot)) return false;
        for (const auto& j : adjacent.at(id)) {
            if (j.robot != robot && !later.count(j.robot)) return false;
        }
        return true;
    };
    return Reach(adjacent, own, depth, joinable);
}

std::vector<slam::LoopClosure> EdgesTouching(const SolverState& me) {
    std::vector<slam::LoopClosure> out = me.OwnEdges();  // odometry and own-tail loops
    for (const auto& l : me.InterRobotLoops()) {
        if (l.b.robot == me.robot() && l.a.robot != me.robot()) out.push_back(l);
    }
    return out;
}

RoundBoundary BoundaryOf(const SolverState& me, int depth) {
    RoundBoundary out;
    out.depth = depth;
    if (depth == 0) return out;
    const std::vector<slam::LoopClosure> edges = EdgesTouching(me);
    Adjacency own;  // through own poses only
    std::set<slam::PoseId> ends;
    for (const auto& e : edges) {
        if (e.a.robot == me.robot() && e.b.robot == me.robot()) {
            own[e.a].push_back(e.b);
            own[e.b].push_back(e.a);
        } else {
            ends.insert(e.a.robot == me.robot() ? e.a : e.b);
        }
    }
    const auto any = [](const slam::PoseId&) { return true; };
    std::set<slam::PoseId> sent = Reach(own, ends, depth, any);
    sent.insert(ends.begin(), ends.end());
    sent.insert({me.robot(), 0});  // the anchor, as PublicPoses
    for (const auto& id : sent) {
        if (id.index >= 0 && id.index < me.NumPoses()) out.sent.push_back(id);
    }
    std::set<slam::PoseId> reachable = Reach(own, ends, depth - 1, any);
    reachable.insert(ends.begin(), ends.end());
    for (const auto& id : reachable) out.proposable.insert(id.index);
    for (const auto& e : edges) {
        if (reachable.count(e.a) || reachable.count(e.b)) out.edges.push_back(e);
    }
    return out;
}

PoseBlocks RoundPoses(const SolverState& me, const RoundBoundary& boundary, std::uint64_t round,
                      std::uint64_t iteration, const OverlapSweep* sweep) {
    if (boundary.depth == 0) return me.PublicPoses(iteration);
    const PoseBlocks full = me.FullBlock(iteration);
    PoseBlocks out;
    out.iteration = iteration;
    out.staircase_level = full.staircase_level;
    const PoseBlocks* proposals = sweep != nullptr ? &sweep->Proposals() : nullptr;
    const Eigen::Index extra =
        proposals != nullptr && proposals->blocks.rows() == full.blocks.rows()
            ? proposals->blocks.cols()
            : 0;
    out.blocks.resize(full.blocks.rows(), kBlock * Eigen::Index(boundary.sent.size()) + extra);
    Eigen::Index c = 0;
    for (const auto& id : boundary.sent) {
        if (id.index >= me.NumPoses()) continue;  // BoundaryOf keeps only poses of the block
        out.ids.push_back(id);
        out.blocks.middleCols(c, kBlock) = full.blocks.middleCols(kBlock * id.index, kBlock);
        c += kBlock;
    }
    if (extra > 0) {
        out.ids.insert(out.ids.end(), proposals->ids.begin(), proposals->ids.end());
        out.blocks.middleCols(c, extra) = proposals->blocks;
        c += extra;
    }
    out.blocks.conservativeResize(Eigen::NoChange, c);
    if (round == 0) out.edges = boundary.edges;
    return out;
}

double SweepRound(const RoundAction& a, int depth, const slam::RbcdConfig& rbcd,
                  const TeamRounds& rounds, SolverState* me, std::optional<OverlapSweep>* sweep) {
    me->SetOwnBlock(a.own_start);
    if (!a.overlap) {
        sweep->reset();  // own poses from here on (TeamRounds::Overlapping): no proposals
        return me->StepTo(a.block_tol).grad_norm;
    }
    if (depth > 0 && !*sweep) {  // from round 1: the colours and the neighbours' edges are in
        std::vector<slam::LoopClosure> edges = EdgesTouching(*me);
        // An edge between two neighbours comes from both; a sender's own edges only from it
        // (parallel odometry and loop edges are distinct terms).
        std::set<std::pair<slam::PoseId, slam::PoseId>> between;
        for (const auto& e : rounds.NeighbourEdges()) {
            if (e.a.robot == e.b.robot || between.insert({e.a, e.b}).second) edges.push_back(e);
        }
        sweep->emplace(me->robot(), me->NumPoses(), me->Rank(), edges,
                       OverlapDomain(me->robot(), edges, depth, rounds.LaterNeighbours()), rbcd);
    }
    if (*sweep && (*sweep)->OverlapSize() > 0) {
        try {
            me->SetOwnBlock((*sweep)->Sweep(a.own_start, me->NeighbourBlocks(), a.block_tol));
            return (*sweep)->GradNorm();
        } catch (const std::invalid_argument&) {
            // A domain pose no neighbour sent (a loop to a pose that never came): own poses only
            // from here on.
            sweep->emplace(me->robot(), me->NumPoses(), me->Rank(),
                           std::vector<slam::LoopClosure>{}, std::set<slam::PoseId>{}, rbcd);
            me->SetOwnBlock(a.own_start);
        }
    }
    return me->StepTo(a.block_tol).grad_norm;
}

}  // namespace certislam::certify
