// Splitting a pose graph into robots' blocks.
#include "slam/core/graph_split.h"

#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>

namespace certislam::slam {
namespace {

Eigen::Isometry3d PoseOf(const RelativePoseMeasurement& e) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = e.R;
    T.translation() = e.t;
    return T;
}

/// Initial guess of every global pose: VERTEX estimates, else the chain g -> g + 1.
std::vector<Eigen::Isometry3d> InitialPoses(const PoseGraph& graph) {
    std::vector<Eigen::Isometry3d> out(graph.n, Eigen::Isometry3d::Identity());
    if (graph.initial_guess) {
        for (int g = 0; g < graph.n; ++g) {
            out[g].linear() = graph.initial_guess->block<3, 3>(0, BlockColumn(g, 3));
            out[g].translation() = graph.initial_guess->block<3, 1>(0, BlockColumn(g, 3) + 3);
        }
        return out;
    }
    std::vector<std::optional<Eigen::Isometry3d>> step(graph.n);
    for (const auto& e : graph.edges) {
        if (e.j == e.i + 1 && !step[e.i]) step[e.i] = PoseOf(e);
    }
    for (int g = 1; g < graph.n; ++g) {
        out[g] = out[g - 1] * step[g - 1].value_or(Eigen::Isometry3d::Identity());
    }
    return out;
}

void CheckInput(const PoseGraph& graph, const Partition& partition) {
    if (graph.d != 3) throw std::invalid_argument("only planar and 3D graphs are split");
    if (partition.begin.size() < 2 || partition.begin.front() != 0 ||
        partition.begin.back() != graph.n) {
        throw std::invalid_argument("the partition must cover poses [0, " +
                                    std::to_string(graph.n) + ")");
    }
    for (size_t k = 0; k + 1 < partition.begin.size(); ++k) {
        if (partition.begin[k] >= partition.begin[k + 1]) {
            throw std::invalid_argument("robot " + std::to_string(k) + " owns no pose");
        }
    }
}

/// [A 0; 0 1] for a d x d block A (d <= 3).
Eigen::Matrix3d Embed(const Eigen::MatrixXd& A) {
    Eigen::Matrix3d out = Eigen::Matrix3d::Identity();
    out.topLeftCorner(A.rows(), A.cols()) = A;
    return out;
}

}  // namespace

MergedGraph MergeParallelEdges(const PoseGraph& graph) {
    MergedGraph out;
    out.graph = graph;
    out.graph.edges.clear();
    std::map<std::pair<int, int>, size_t> first;  // (tail, head) -> merged edge
    std::vector<std::vector<size_t>> groups;
    for (size_t k = 0; k < graph.edges.size(); ++k) {
        const auto& e = graph.edges[k];
        const auto [it, fresh] = first.emplace(std::pair{e.i, e.j}, groups.size());
        if (fresh) {
            groups.emplace_back();
        } else {
            ++out.merged;
        }
        groups[it->second].push_back(k);
    }
    for (const auto& group : groups) {
        RelativePoseMeasurement m = graph.edges[group.front()];
        if (group.size() > 1) {
            m.R.setZero();
            m.t.setZero();
            m.kappa = m.tau = 0.0;
            for (const size_t k : group) {
                const auto& e = graph.edges[k];
                m.kappa += e.kappa;
                m.tau += e.tau;
                m.R += e.kappa * e.R;
                m.t += e.tau * e.t;
            }
            m.R /= m.kappa;
            m.t /= m.tau;
        }
        // The constant as a sum of squares (exact to rounding, >= 0); the rotation terms have none.
        double cost = 0.0;
        for (const size_t k : group) {
            cost += graph.edges[k].tau * (graph.edges[k].t - m.t).squaredNorm();
        }
        out.graph.edges.push_back(std::move(m));
        out.cost.push_back(group.size() > 1 ? cost : 0.0);
    }
    return out;
}

double CostOffset(const std::vector<RobotGraph>& graphs) {
    double sum = 0.0;
    for (const auto& g : graphs) sum += g.cost_offset;
    return sum;
}

PoseGraph LiftPlanar(const PoseGraph& graph) {
    if (graph.d != 2) return graph;
    PoseGraph out = graph;
    out.d = 3;
    for (auto& e : out.edges) {
        e.R = Embed(e.R);
        e.t = Eigen::Vector3d(e.t(0), e.t(1), 0.0);
    }
    if (graph.initial_guess) {
        Eigen::MatrixXd lifted = Eigen::MatrixXd::Zero(3, 4 * graph.n);
        for (int g = 0; g < graph.n; ++g) {
            const Eigen::MatrixXd& block = *graph.initial_guess;
            lifted.block<3, 3>(0, BlockColumn(g, 3)) =
                Embed(block.block(0, BlockColumn(g, 2), 2, 2));
            lifted.block<2, 1>(0, BlockColumn(g, 3) + 3) =
                block.block<2, 1>(0, BlockColumn(g, 2) + 2);
        }
        out.initial_guess = lifted;
    }
    return out;
}

std::vector<RobotGraph> SplitGraph(const PoseGraph& planar_or_3d, const Partition& partition) {
    const PoseGraph lifted = LiftPlanar(planar_or_3d);
    CheckInput(lifted, partition);
    const std::vector<Eigen::Isometry3d> initial = InitialPoses(lifted);  // file's edges: rotations
    const MergedGraph merged = MergeParallelEdges(lifted);
    const PoseGraph& graph = merged.graph;
    std::vector<RobotGraph> out(partition.num_robots());
    const auto id = [&](int g) {
        const int robot = partition.RobotOf(g);
        return PoseId{robot, g - partition.begin[robot]};
    };
    for (int k = 0; k < partition.num_robots(); ++k) {
        out[k].robot = k;
        for (int g = partition.begin[k]; g < partition.begin[k + 1]; ++g) {
            out[k].initial.push_back(initial[g]);
        }
    }
    for (size_t k = 0; k < graph.edges.size(); ++k) {
        const auto& e = graph.edges[k];
        LoopClosure l;
        l.a = id(e.i);
        l.b = id(e.j);
        l.T_a_b = PoseOf(e);
        l.kappa = e.kappa;
        l.tau = e.tau;
        l.sc_distance = 0.0;
        out[l.a.robot].cost_offset += merged.cost[k];
        if (!l.inter_robot()) {
            out[l.a.robot].intra.push_back(l);
        } else {
            out[l.a.robot].inter.push_back(l);
            out[l.b.robot].shared.push_back(l);
        }
    }
    return out;
}

}  // namespace certislam::slam
