// The state of one robot's TeamFinish (team_finish.h), shared by its two source files: the trust
// region's phase machine (team_finish.cpp) and its Steihaug-CG iterations (team_finish_cg.cpp).
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "certify/pipeline/team_finish.h"
#include "certify/pipeline/team_finish_domain.h"
#include "certify/pipeline/team_finish_rows.h"

namespace certislam::certify {
namespace finish_detail {

constexpr int kBlock = 4;  // d + 1 columns per pose (d = 3)
constexpr int kD = 3;
constexpr int kFlatSteps = 3;  // steps without halving the gradient that make a floor

inline double Inner(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B) {
    return A.cwiseProduct(B).sum();
}

}  // namespace finish_detail

struct TeamFinish::Impl {
    static constexpr int kBlock = finish_detail::kBlock;
    static constexpr int kD = finish_detail::kD;

    // With overlap, a CG iteration is three message hops: the scatter of z with the sums of
    // <r, z> (each domain's own term), the product's delta, and H delta's entries on the
    // neighbours' domains with the sum of <delta, H delta>, from which every robot updates its
    // copy of the neighbours' r itself (no gather but at a step's first iteration).
    enum class Phase {
        kStartX,     // exchange: the neighbours' entries of the starting X
        kStartSums,  // sum: f, ||grad||^2
        kGather,     // exchange: the neighbours' entries of r on the own domain (a step's first)
        kScatter,    // exchange: the neighbours' shares of z at the own poses; sum: <r, z>, ||r||^2
        kPrecSums,   // (overlap 0) sum: <r, z>, ||r||^2
        kProduct,    // exchange: the neighbours' entries of delta
        kCurvSums,   // sum: <delta, H delta>; exchange (overlap): H delta on the own domain
        kCandidate,  // exchange: the neighbours' entries of the candidate X+
        kCandSums,   // sum: f(X+), <grad, eta>, <eta, H eta>, ||grad(X+)||^2, f(X+) - f(X)
        kDone,
    };

    int robot;
    std::vector<int> team;
    TeamFinishConfig config;
    FinishRows rows;
    const std::vector<slam::PoseId>& own_ids;
    std::set<int> neighbours;
    std::map<int, std::vector<slam::PoseId>> read_from;  // own poses each neighbour reads
    FinishDomain domain;
    std::set<int> edges_from;  // neighbours whose domain edges are in
    Status status = Status::kRunning;
    Phase phase = Phase::kStartX;
    TeamFinishProgress progress;

    FinishPoint at, cand;
    double f = 0.0, g = 0.0;  // team sums at `at`
    // Steihaug-CG state (own columns) and its scalars (team).
    Eigen::MatrixXd r, z, delta, Hd, eta, Heta;
    std::map<slam::PoseId, Eigen::MatrixXd> r_nbr;  // the neighbours' r on the own domain
    double rz = 0.0, alpha = 0.0, e_Pe = 0.0, e_Pd = 0.0, d_Pd = 0.0, stop = 0.0;
    double radius = -1.0, max_radius = 0.0, tol = 0.0;
    int tcg = 0;
    bool initial_prec = true;
    bool hit_boundary_ = false;
    bool started = false;
    bool spoiled = false;  // a local failure: this robot's next share of a sum is not finite
    double best_g = std::numeric_limits<double>::infinity();
    int flat_steps = 0;  // trust-region steps since the gradient last halved

    std::uint64_t exchange = 0, reduction = 0;  // the next ones
    std::map<std::uint64_t, FinishEntries> vectors;
    std::map<std::uint64_t, std::map<int, std::vector<double>>> sums;
    std::vector<FinishEdges> out_edges;
    std::vector<FinishVector> out_vectors;
    std::vector<FinishSums> out_sums;

    Impl(int robot_id, std::vector<int> robots, const Eigen::MatrixXd& X_own,
         std::vector<slam::LoopClosure> own_edges, TeamFinishConfig c)
        : robot(robot_id),
          team(std::move(robots)),
          config(c),
          rows(robot_id, int(X_own.cols() / kBlock), std::move(own_edges)),
          own_ids(rows.OwnIds()),
          domain(robot_id, int(X_own.cols() / kBlock), rows.Edges(), c.overlap, c.regulariser) {
        config.Validate();
        std::set<int> unique(team.begin(), team.end());
        if (unique.size() != team.size() || !unique.count(robot))
            throw std::invalid_argument("TeamFinish: the team must hold robot " +
                                        std::to_string(robot) + " and every robot once");
        read_from = rows.ReadBy();
        for (const auto& [j, ids] : read_from) neighbours.insert(j);
        at.X = X_own;
    }

    // --- messages -------------------------------------------------------------------------
    void SendEach(const std::map<int, Eigen::MatrixXd>& by_robot,
                  const std::map<int, std::vector<slam::PoseId>>& ids) {
        for (int j : neighbours) {
            FinishVector v{j, exchange, ids.count(j) ? ids.at(j) : std::vector<slam::PoseId>{},
                           by_robot.at(j)};
            progress.entries_sent += double(v.blocks.size());
            out_vectors.push_back(std::move(v));
        }
        ++exchange;
        ++progress.exchanges;
    }
    // Sends the own entries of `own` at the poses each neighbour reads (delta), and with
    // `with_anchor` own pose 0 too (X and X+: the frame the neighbours' trajectories use).
    void SendRead(const Eigen::MatrixXd& own, bool with_anchor) {
        std::map<int, Eigen::MatrixXd> blocks;
        std::map<int, std::vector<slam::PoseId>> ids = read_from;
        for (int j : neighbours) {
            auto& list = ids[j];
            if (with_anchor && !own_ids.empty() && (list.empty() || list.front() != own_ids[0]))
                list.insert(list.begin(), own_ids[0]);
            blocks[j] = OwnColumns(own, list);
        }
        SendEach(blocks, ids);
    }
    void SendSums(std::vector<double> values) {
        if (spoiled)
            std::fill(values.begin(), values.end(), std::numeric_limits<double>::quiet_NaN());
        out_sums.push_back({reduction++, std::move(values)});
        ++progress.reductions;
    }
    // The own entries of `own` at the own poses in each neighbour's domain (r, H delta).
    void SendDomainEntries(const Eigen::MatrixXd& own) {
        std::map<int, Eigen::MatrixXd> blocks;
        std::map<int, std::vector<slam::PoseId>> ids;
        for (int j : neighbours) {
            ids[j] = domain.OwnPosesIn(j);
            blocks[j] = OwnColumns(own, ids[j]);
        }
        SendEach(blocks, ids);
    }
    // The last exchange's messages once every neighbour's is in.
    FinishEntries* Received() {
        auto it = vectors.find(exchange - 1);
        if (neighbours.empty()) return &vectors[exchange - 1];
        return it != vectors.end() && it->second.size() == neighbours.size() ? &it->second
                                                                             : nullptr;
    }
    // The team's sums of the last reduction, added in team order (the same bits everywhere);
    // a share of another length or not finite (a robot's local failure: Spoil) ends every
    // robot's finish at this same reduction.
    bool Reduced(size_t expected, std::vector<double>* out) {
        auto it = sums.find(reduction - 1);
        if (it == sums.end() || it->second.size() != team.size()) return false;
        std::vector<double> total(expected, 0.0);
        for (int k : team) {
            const auto& v = it->second.at(k);
            const bool finite =
                std::all_of(v.begin(), v.end(), [](double x) { return std::isfinite(x); });
            if (v.size() != expected || !finite) {
                Finish(Status::kInconsistent);
                return false;
            }
            for (size_t i = 0; i < v.size(); ++i) total[i] += v[i];
        }
        sums.erase(it);
        *out = std::move(total);
        return true;
    }
    // A local failure (a neighbour's entries missing, a factor failed): this robot goes on
    // sending every exchange its neighbours wait for (empty or zero where it has nothing) and a
    // non-finite share of the next sum, so that every robot ends there (Reduced).
    void Spoil() { spoiled = true; }

    void Finish(Status s) {
        status = s;
        phase = Phase::kDone;
        progress.cost = f;
        progress.grad_norm = g;
    }

    void Advance();
    bool Step();
    void BeginIteration();
    void StartPrecondition();
    void SolveDomain();
    bool Gathered();
    bool ApplyScatter();
    void OnPrecSums(const std::vector<double>& s);
    void OnCurvSums(double dHd, const std::map<slam::PoseId, Eigen::MatrixXd>& hd_nbr);
    void EndTcg();
    bool OnCandidate();
    void OnCandSums(const std::vector<double>& s);
};

}  // namespace certislam::certify
