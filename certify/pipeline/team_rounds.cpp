// Synchronous RBCD++ rounds of one robot: which poses a sweep starts from, when the team's sums
// are complete, and the accept / restart / stop rule every robot applies to the same sums.
#include "certify/pipeline/team_rounds.h"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <stdexcept>
#include <string>
#include <utility>

#include "slam/backend/stiefel.h"

namespace certislam::certify {
namespace {

constexpr int kDimension = 3;
constexpr int kBlock = kDimension + 1;  // columns per lifted pose
// A rise of f below this relative size is the rounding noise of the robots' summed shares near
// the optimum, not an overshoot: it does not restart the extrapolation.
constexpr double kCostNoise = 1e-14;
// Once a kept extrapolated round changes f by at most this relative amount, f's changes are too
// small to show the extrapolation overshooting; the gradient norm still shows it, and a rise of
// it resets the extrapolation (a gradient-norm heuristic in the spirit of O'Donoghue and
// Candes' adaptive restart, whose gradient test is grad^T (x_k - x_{k-1}) > 0).
constexpr double kFlatCost = 1e-9;

/// RBCD++ (Alg. 3): Proj(X_a + beta (X_a - X_b)) pose by pose; X_a itself when beta is 0.
Eigen::MatrixXd Extrapolate(const Eigen::MatrixXd& X_a, const Eigen::MatrixXd& X_b, double beta) {
    if (beta == 0.0 || X_a.cols() != X_b.cols() || X_a.rows() != X_b.rows()) return X_a;
    return slam::ProjectToManifold(X_a + beta * (X_a - X_b), kDimension);
}

/// True when block k of `blocks` is finite and its rotation part is on St(d, r): a pose of the
/// lifted manifold, which a sweep may start from.
bool IsLiftedPose(const Eigen::MatrixXd& blocks, Eigen::Index k) {
    constexpr double kOrthonormalTol = 1e-6;
    if (blocks.cols() < kBlock * (k + 1) || blocks.rows() < kDimension) return false;
    const auto pose = blocks.middleCols(kBlock * k, kBlock);
    if (!pose.allFinite()) return false;
    const Eigen::MatrixXd Y = pose.leftCols(kDimension);
    return (Y.transpose() * Y - Eigen::MatrixXd::Identity(kDimension, kDimension))
               .cwiseAbs()
               .maxCoeff() <= kOrthonormalTol;
}

/// The poses of `sender` in its message `p` (ids and blocks), without its proposals for others.
std::pair<std::vector<slam::PoseId>, Eigen::MatrixXd> SendersOwn(const PoseBlocks& p, int sender) {
    std::pair<std::vector<slam::PoseId>, Eigen::MatrixXd> out;
    out.second.resize(p.blocks.rows(), p.blocks.cols());
    Eigen::Index kept = 0;
    for (size_t k = 0; k < p.ids.size(); ++k) {
        if (p.ids[k].robot != sender) continue;
        out.first.push_back(p.ids[k]);
        out.second.middleCols(kept, kBlock) = p.blocks.middleCols(kBlock * Eigen::Index(k), kBlock);
        kept += kBlock;
    }
    out.second.conservativeResize(Eigen::NoChange, kept);
    return out;
}

}  // namespace

TeamRounds::TeamRounds(int robot, std::vector<int> robots, std::set<int> neighbours,
                       TeamRoundsConfig config)
    : robot_(robot),
      robots_(std::move(robots)),
      neighbours_(std::move(neighbours)),
      config_(config),
      overlapping_(config.overlap_depth > 0) {
    if (!(config_.rel_grad_tol > 0.0) || config_.max_rounds < 1 ||
        !(config_.local_tol_factor > 0.0 && config_.local_tol_factor <= 1.0) ||
        !(config_.refine_rel_grad_tol > 0.0 &&
          config_.refine_rel_grad_tol <= config_.rel_grad_tol) ||
        config_.refine_rounds < 0 || config_.overlap_depth < 0 || config_.overlap_depth > 16 ||
        config_.hand_over_after < 0) {
        throw std::invalid_argument(
            "TeamRoundsConfig: rel_grad_tol = " + std::to_string(config_.rel_grad_tol) +
            " must be > 0, refine_rel_grad_tol = " + std::to_string(config_.refine_rel_grad_tol) +
            " in (0, rel_grad_tol], refine_rounds = " + std::to_string(config_.refine_rounds) +
            " >= 0, local_tol_factor = " + std::to_string(config_.local_tol_factor) +
            " in (0, 1], max_rounds = " + std::to_string(config_.max_rounds) +
            " >= 1, overlap_depth = " + std::to_string(config_.overlap_depth) + " in [0, 16]");
    }
}

void TeamRounds::OnPoses(int robot, std::uint64_t round, const PoseBlocks& poses) {
    if (neighbours_.count(robot) == 0 || round + 1 < accepted_prev_) return;
    if (round == 0) {  // the first one stays
        colors_.emplace(robot, poses.sweep_color);
        // Only the sender's edges that this robot does not hold itself (those touching its poses).
        std::vector<slam::LoopClosure> theirs;
        std::copy_if(poses.edges.begin(), poses.edges.end(), std::back_inserter(theirs),
                     [&](const slam::LoopClosure& e) {
                         return (e.a.robot == robot || e.b.robot == robot) && e.a.robot != robot_ &&
                                e.b.robot != robot_;
                     });
        edges_.emplace(robot, std::move(theirs));
    }
    nbr_[robot][round] = poses;
}

bool TeamRounds::Earlier(int j, std::uint64_t round) const {
    if (round == 0) return j < robot_;
    // A neighbour's colour is in before round 1 (round 0's evaluation waits for its poses); two
    // neighbours never share one (the higher avoided the lower's), so both see the same order.
    const auto it = colors_.find(j);
    return it == colors_.end() ? j < robot_ : it->second < color_;
}

void TeamRounds::OnSums(int robot, std::uint64_t round, double cost, double grad_norm) {
    // Only the team's robots decide a round (sums_ counts them), each with finite sums.
    if (round < current_ || std::find(robots_.begin(), robots_.end(), robot) == robots_.end() ||
        !std::isfinite(cost) || !std::isfinite(grad_norm)) {
        return;
    }
    sums_[round][robot] = {cost, grad_norm * grad_norm};
    if (robot == robot_ && round == current_) evaluated_ = true;
}

bool TeamRounds::HaveNeighbour(int j, std::uint64_t round, bool lower_only) const {
    return !MissingRound(j, round, lower_only).has_value();
}

std::optional<std::uint64_t> TeamRounds::MissingRound(int j, std::uint64_t round,
                                                      bool lower_only) const {
    const auto it = nbr_.find(j);
    const auto lacks = [&](std::uint64_t r) { return it == nbr_.end() || !it->second.count(r); };
    if (Earlier(j, round) || !lower_only) {
        if (lacks(round)) return round;
        return std::nullopt;
    }
    if (round == 0) return std::nullopt;  // placement waits for lower neighbours only
    if (lacks(accepted_)) return accepted_;
    if (beta_ != 0.0 && lacks(accepted_prev_)) return accepted_prev_;
    return std::nullopt;
}

bool TeamRounds::HaveNeighbours(std::uint64_t round, bool lower_only) const {
    return std::all_of(neighbours_.begin(), neighbours_.end(),
                       [&](int j) { return HaveNeighbour(j, round, lower_only); });
}

std::vector<RoundWant> TeamRounds::Wants() const {
    std::vector<RoundWant> out;
    if (converged_ || handed_over_ || current_ > static_cast<std::uint64_t>(config_.max_rounds)) {
        return out;
    }
    const bool sweep = own_.count(current_) == 0;
    if (sweep || !evaluated_) {
        for (int j : neighbours_) {
            if (const auto r = MissingRound(j, current_, sweep)) out.push_back({j, *r, false});
        }
        return out;
    }
    const auto it = sums_.find(current_);
    for (int r : robots_) {
        if (it == sums_.end() || it->second.count(r) == 0) out.push_back({r, current_, true});
    }
    return out;
}

std::string TeamRounds::Waiting() const {
    const auto wants = Wants();
    if (wants.empty()) return "";
    std::string out = "round " + std::to_string(current_) + ": the " +
                      (wants.front().sums ? "sums" : "poses") + " of robot";
    out += wants.size() > 1 ? "s" : "";
    for (size_t k = 0; k < wants.size() && k < kWaitingListed; ++k) {
        out += (k == 0 ? " " : ", ") + std::to_string(wants[k].robot);
    }
    if (wants.size() > kWaitingListed) {
        out += " and " + std::to_string(wants.size() - kWaitingListed) + " more";
    }
    return out;
}

PoseBlocks TeamRounds::NeighbourPoses(std::uint64_t round, bool extrapolate_higher) const {
    PoseBlocks out;
    std::vector<Eigen::MatrixXd> parts;
    Eigen::Index cols = 0, rows = 0;
    for (int j : neighbours_) {
        if (round == 0 && extrapolate_higher && j > robot_) continue;  // placement: lower only
        const auto& by_round = nbr_.at(j);
        // The sender's own poses only: its proposals for other robots' poses (an overlapping
        // sweep) are for those robots, which start from them (ApplyProposals).
        std::pair<std::vector<slam::PoseId>, Eigen::MatrixXd> mine;
        if (extrapolate_higher && !Earlier(j, round)) {
            mine = SendersOwn(by_round.at(accepted_), j);
            const auto prev = by_round.find(accepted_prev_);
            if (prev != by_round.end()) {
                const auto before = SendersOwn(prev->second, j);
                if (before.first == mine.first) {
                    mine.second = Extrapolate(mine.second, before.second, beta_);
                }
            }
        } else {
            mine = SendersOwn(by_round.at(round), j);
        }
        out.ids.insert(out.ids.end(), mine.first.begin(), mine.first.end());
        rows = mine.second.rows();
        cols += mine.second.cols();
        parts.push_back(std::move(mine.second));
    }
    out.blocks.resize(rows, cols);
    Eigen::Index c = 0;
    for (const auto& part : parts) {
        out.blocks.middleCols(c, part.cols()) = part;
        c += part.cols();
    }
    return out;
}

void TeamRounds::ApplyProposals(std::uint64_t round, Eigen::MatrixXd* own_start) {
    // In sweep order: a pose two earlier neighbours proposed takes the later sweeper's proposal.
    std::vector<std::pair<int, int>> earlier;  // (colour, robot)
    for (int j : neighbours_) {
        if (Earlier(j, round)) earlier.emplace_back(colors_.count(j) ? colors_.at(j) : 0, j);
    }
    std::sort(earlier.begin(), earlier.end());
    const bool count = counted_ != round;  // a second Next() before SweepDone counts nothing
    counted_ = round;
    for (const auto& [color, j] : earlier) {
        const auto& p = nbr_.at(j).at(round);  // HaveNeighbours: an earlier one's poses are in
        for (size_t k = 0; k < p.ids.size(); ++k) {
            const slam::PoseId& id = p.ids[k];
            if (id.robot != robot_) continue;  // the sender's own poses or another robot's
            if (!overlapping_ || !proposable_.count(id.index) ||
                kBlock * Eigen::Index(id.index + 1) > own_start->cols() ||
                p.blocks.rows() != own_start->rows() || !IsLiftedPose(p.blocks, Eigen::Index(k))) {
                if (count) ++rejected_;
                continue;
            }
            own_start->middleCols(kBlock * Eigen::Index(id.index), kBlock) =
                p.blocks.middleCols(kBlock * Eigen::Index(k), kBlock);
        }
    }
}

std::set<int> TeamRounds::LaterNeighbours() const {
    std::set<int> out;
    for (int j : neighbours_) {
        if (!Earlier(j, 1)) out.insert(j);
    }
    return out;
}

std::vector<slam::LoopClosure> TeamRounds::NeighbourEdges() const {
    std::vector<slam::LoopClosure> out;
    for (const auto& [robot, edges] : edges_) out.insert(out.end(), edges.begin(), edges.end());
    return out;
}

RoundAction TeamRounds::Next() {
    RoundAction a;
    if (converged_) {
        a.kind = RoundAction::Kind::kConverged;
        a.round = accepted_;
        a.own_start = own_.at(accepted_);
        a.neighbours = NeighbourPoses(accepted_, false);
        return a;
    }
    if (handed_over_ || current_ > static_cast<std::uint64_t>(config_.max_rounds)) {
        a.kind = RoundAction::Kind::kGaveUp;
        return a;
    }
    a.round = current_;
    if (own_.count(current_) == 0) {  // RBCD++ Alg. 3: the sweep from the extrapolated point
        if (!HaveNeighbours(current_, true)) return a;
        if (current_ == 0) {
            std::set<int> taken;
            for (int j : neighbours_) {
                if (j < robot_) taken.insert(colors_.at(j));  // their round-0 poses are in
            }
            while (taken.count(color_)) ++color_;
            a.kind = RoundAction::Kind::kAlign;
            a.neighbours = NeighbourPoses(0, true);
            return a;
        }
        a.kind = RoundAction::Kind::kSweep;
        const auto prev = own_.find(accepted_prev_);
        a.own_start = Extrapolate(own_.at(accepted_), prev->second, beta_);
        ApplyProposals(current_, &a.own_start);
        a.neighbours = NeighbourPoses(current_, true);
        a.overlap = overlapping_;
        // MATH.md: the local tolerance must be tighter than the global one.
        a.block_tol = config_.local_tol_factor * TeamTolerance() * std::max(1.0, accepted_cost_);
        return a;
    }
    if (!evaluated_) {
        if (!HaveNeighbours(current_, false)) return a;
        a.kind = RoundAction::Kind::kEvaluate;
        a.neighbours = NeighbourPoses(current_, false);
        return a;
    }
    if (sums_[current_].size() < robots_.size()) return a;
    Decide();
    return Next();
}

void TeamRounds::SweepDone(std::uint64_t round, const Eigen::MatrixXd& own_candidate) {
    if (round != current_) return;
    own_[round] = own_candidate;
    if (round > 0) ++swept_;
}

void TeamRounds::Decide() {
    double f = 0.0, grad_sq = 0.0;
    for (const auto& [robot, s] : sums_[current_]) {
        f += s.first;
        grad_sq += s.second;
    }
    // Adaptive restart: an extrapolated round whose cost rose is dropped and the next round sweeps
    // from the last accepted point without extrapolation (RBCD++, restart scheme of AMM-PGO).
    const bool rose =
        current_ > 0 && f > accepted_cost_ + kCostNoise * std::max(1.0, accepted_cost_);
    // Without extrapolation, on a fixed graph, only an overlapping sweep raises f: dropped too,
    // and own-pose sweeps (which lower f) for the rest of these rounds.
    const bool overlap_rose = rose && beta_ == 0.0 && overlapping_;
    if (overlap_rose) {
        overlapping_ = false;
        overlap_ended_ = current_;
    }
    const bool accept =
        !overlap_rose && (current_ == 0 || !config_.acceleration || plain_ || !rose);
    const double grad = std::sqrt(grad_sq), scale = std::max(1.0, f);
    // The round is kept (it did not raise f) but its momentum is spent: the next one sweeps
    // without extrapolation, and the extrapolation builds up again from there.
    const bool grad_rose =
        accept && current_ > 0 && beta_ > 0.0 && grad > accepted_grad_ &&
        std::abs(f - accepted_cost_) <= kFlatCost * std::max(1.0, accepted_cost_);
    if (accept) {
        if (current_ > 0) accepted_prev_ = accepted_;
        accepted_ = current_;
        accepted_cost_ = f;
        accepted_grad_ = grad;
        if (!within_ && grad <= config_.rel_grad_tol * scale) within_ = current_;
        // Refined, or out of refinement rounds (the rounds' own budget included) at a point
        // still within rel_grad_tol: an accepted round lowers f, not always the gradient.
        const auto last = static_cast<std::uint64_t>(config_.max_rounds);
        const bool spent =
            within_ &&
            current_ >=
                std::min(*within_ + static_cast<std::uint64_t>(config_.refine_rounds), last);
        converged_ = grad <= config_.refine_rel_grad_tol * scale ||
                     (spent && grad <= config_.rel_grad_tol * scale);
        handed_over_ = !converged_ && RateTooSlow(grad, scale);
        const bool reset = grad_rose && !converged_;  // a last round has no next one to reset
        gamma_ = plain_ || reset ? 1.0 : gamma_next_;
        if (reset) ++restarts_;
    } else {
        ++restarts_;
        gamma_ = 1.0;
    }
    plain_ = !accept;
    best_grads_.push_back(std::min(accepted_grad_, best_grads_.empty()
                                                       ? accepted_grad_
                                                       : best_grads_.back()));  // after round k
    ++current_;
    evaluated_ = false;
    gamma_next_ = 0.5 * (1.0 + std::sqrt(1.0 + 4.0 * gamma_ * gamma_));
    beta_ = config_.acceleration && !plain_ ? (gamma_ - 1.0) / gamma_next_ : 0.0;
    Prune();
}

// The gradient's low fell at a rate over the last kRateWindow rounds (RBCD's tail is linear) at
// which rel_grad_tol comes after kHopeless * max_rounds, or never. The low, not the last value:
// accelerated rounds are not monotone. Every robot decides it from the same sums.
bool TeamRounds::RateTooSlow(double grad, double scale) const {
    if (config_.hand_over_after <= 0 || within_ ||
        current_ < std::max<std::uint64_t>(config_.hand_over_after, kRateWindow) ||
        best_grads_.size() < kRateWindow) {
        return false;
    }
    // The smallest gradient so far, then and now: accelerated rounds are not monotone.
    const double before = best_grads_[current_ - kRateWindow];
    const double best = std::min(grad, best_grads_.back());
    const double target = config_.rel_grad_tol * scale;
    if (!(best < before) || !(best > 0.0)) return true;  // no new low over the window
    const double per_round = std::log(best / before) / double(kRateWindow);  // < 0
    const double remaining = std::log(target / best) / per_round;
    return double(current_) + remaining > kHopeless * double(config_.max_rounds);
}

double TeamRounds::TeamTolerance() const {
    return within_ ? config_.refine_rel_grad_tol : config_.rel_grad_tol;
}

void TeamRounds::Prune() {
    const std::uint64_t keep = std::min(accepted_prev_, accepted_);
    std::erase_if(own_, [&](const auto& e) { return e.first < keep; });
    for (auto& [robot, by_round] : nbr_) {
        std::erase_if(by_round, [&](const auto& e) { return e.first < keep; });
    }
    std::erase_if(sums_, [&](const auto& e) { return e.first < current_; });
}

}  // namespace certislam::certify
