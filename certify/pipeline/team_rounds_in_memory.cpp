// Synchronous RBCD++ rounds of a team in one thread: the solver actor's actions (SyncAction),
// every robot's poses and sums handed to every other robot at once.
#include "certify/pipeline/team_rounds_in_memory.h"

#include "certify/pipeline/overlap_sweep.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>
#include <utility>

namespace certislam::certify {

InMemoryTeam RunTeamRoundsInMemory(const std::vector<slam::RobotGraph>& graphs, SolverConfig solver,
                                   const TeamRoundsConfig& rounds) {
    solver.odometry_edges = false;  // every edge comes from the graph, as loops
    std::vector<int> ids;
    ids.reserve(graphs.size());
    for (const auto& g : graphs) ids.push_back(g.robot);
    InMemoryTeam team;
    std::vector<TeamRounds> schedule;
    std::vector<std::optional<OverlapSweep>> overlapping(graphs.size());
    std::vector<RoundBoundary> boundaries;
    for (const auto& g : graphs) {
        SolverState state(g.robot, solver);
        for (size_t k = 0; k < g.initial.size(); ++k) state.AddKeyframe(int(k), g.initial[k]);
        for (const auto* part : {&g.intra, &g.inter, &g.shared}) {
            for (const auto& e : *part) state.AddLoop(e);
        }
        state.LocalChordalStart();
        const auto nbrs = state.Neighbours();
        schedule.emplace_back(g.robot, ids, std::set<int>(nbrs.begin(), nbrs.end()), rounds);
        boundaries.push_back(BoundaryOf(state, rounds.overlap_depth));
        schedule.back().SetProposable(boundaries.back().proposable);
        team.robots.push_back(std::move(state));
    }
    using K = RoundAction::Kind;
    std::vector<K> ended(graphs.size(), K::kWait);
    for (bool moved = true; moved;) {
        moved = false;
        for (size_t i = 0; i < graphs.size(); ++i) {
            SolverState& me = team.robots[i];
            for (RoundAction a = schedule[i].Next(); a.kind != K::kWait && ended[i] == K::kWait;
                 a = schedule[i].Next()) {
                moved = true;
                if (a.kind == K::kGaveUp) {
                    ended[i] = a.kind;
                    break;
                }
                me.SetNeighbourPoses(a.neighbours);
                if (a.kind == K::kConverged) {
                    me.SetOwnBlock(a.own_start);
                    ended[i] = a.kind;
                } else if (a.kind == K::kEvaluate) {
                    const auto e = me.Evaluate();
                    for (auto& peer : schedule)
                        peer.OnSums(me.robot(), a.round, e.cost, e.grad_norm);
                } else {
                    if (a.kind == K::kAlign) {
                        me.AlignToLowerNeighbour();
                    } else {
                        SweepRound(a, rounds.overlap_depth, solver.rbcd, schedule[i], &me,
                                   &overlapping[i]);
                    }
                    schedule[i].SweepDone(a.round, me.FullBlock(0).blocks);
                    const OverlapSweep* sweep = overlapping[i] ? &*overlapping[i] : nullptr;
                    PoseBlocks poses = RoundPoses(me, boundaries[i], a.round, 0, sweep);
                    poses.sweep_color = schedule[i].SweepColor();
                    for (auto& peer : schedule) peer.OnPoses(me.robot(), a.round, poses);
                }
            }
        }
    }
    for (size_t i = 0; i < graphs.size(); ++i) {
        team.converged.push_back(ended[i] == K::kConverged);
        team.rounds.push_back(schedule[i].Rounds());
        team.restarts.push_back(schedule[i].Restarts());
        team.rejected_proposals.push_back(schedule[i].RejectedProposals());
    }
    return team;
}

InMemoryFinish RunTeamFinishInMemory(InMemoryTeam* team, const TeamFinishConfig& config) {
    std::vector<int> ids;
    for (const auto& robot : team->robots) ids.push_back(robot.robot());
    std::vector<TeamFinish> finish;
    std::map<int, size_t> index;
    for (const auto& robot : team->robots) {
        index[robot.robot()] = finish.size();
        finish.emplace_back(robot.robot(), ids, robot.FullBlock(0).blocks, EdgesTouching(robot),
                            config);
    }
    InMemoryFinish out;
    for (auto& f : finish) f.Start();
    for (bool moved = true; moved;) {
        moved = false;
        for (size_t i = 0; i < finish.size(); ++i) {
            const int from = ids[i];
            for (const auto& e : finish[i].TakeEdges()) {
                moved = true;
                out.edges += e.edges.size();
                finish[index.at(e.to)].OnEdges(from, e.poses, e.edges);
            }
            for (const auto& v : finish[i].TakeVectors()) {
                moved = true;
                out.entries += double(v.blocks.size());
                finish[index.at(v.to)].OnVector(from, v.step, v.ids, v.blocks);
            }
            for (const auto& s : finish[i].TakeSums()) {
                moved = true;
                out.scalars += double(s.values.size());
                for (auto& peer : finish) peer.OnSums(from, s.step, s.values);
            }
        }
    }
    for (size_t i = 0; i < finish.size(); ++i) {
        out.status.push_back(finish[i].status());
        team->robots[i].SetNeighbourPoses(finish[i].NeighbourPoses());
        team->robots[i].SetOwnBlock(finish[i].Block());
    }
    for (const auto& f : finish) out.progress.push_back(f.Progress());
    return out;
}

bool InMemoryFinish::AllConverged() const {
    return !status.empty() && std::all_of(status.begin(), status.end(), [](TeamFinish::Status s) {
        return s == TeamFinish::Status::kConverged;
    });
}

bool InMemoryTeam::AllConverged() const {
    return std::all_of(converged.begin(), converged.end(), [](bool c) { return c; });
}

double InMemoryTeam::Cost() {
    double f = 0.0;
    for (auto& me : robots) f += me.Evaluate().cost;
    return f;
}

double InMemoryTeam::GradientNorm() {
    double sq = 0.0;
    for (auto& me : robots) sq += std::pow(me.Evaluate().grad_norm, 2);
    return std::sqrt(sq);
}

Eigen::MatrixXd InMemoryTeam::X() const {
    std::vector<Eigen::MatrixXd> blocks;
    Eigen::Index cols = 0;
    for (const auto& robot : robots) {
        blocks.push_back(robot.FullBlock(0).blocks);
        cols += blocks.back().cols();
    }
    Eigen::MatrixXd X(blocks.empty() ? 0 : blocks.front().rows(), cols);
    cols = 0;
    for (const auto& b : blocks) {
        X.middleCols(cols, b.cols()) = b;
        cols += b.cols();
    }
    return X;
}

}  // namespace certislam::certify
