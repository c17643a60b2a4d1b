// What every participant of a round shares: the setup sums and the first-order rule, and the
// buffering of neighbours' entries and robots' partial sums until they are used.
#include "certify/distributed/round_participant.h"

#include <algorithm>
#include <cmath>

#include "certify/distributed/distributed_lanczos.h"

namespace certislam::certify {

std::vector<double> SetupShares(const LocalCertificateProblem& problem,
                                const std::vector<double>& extra) {
    std::vector<double> shares(kSetupShared);
    shares[kSetupCost] = problem.cost;
    shares[kSetupGradientSq] = problem.gradient_sq;
    shares[kSetupQRowSum] = problem.q_row_sum;
    shares[kSetupTraceLambda] = problem.rows.trace_lambda;
    shares[kSetupDimension] = static_cast<double>(problem.rows.own.rows());
    shares[kSetupXNormSq] = problem.x_norm_sq;
    shares[kSetupObjectiveNoise] = problem.objective_noise;
    shares.insert(shares.end(), extra.begin(), extra.end());
    return shares;
}

bool ReadSetupSums(const std::vector<double>& sums, int d, const LanczosSettings& settings,
                   DistributedVerdict* v) {
    v->cost = sums[kSetupCost];
    v->gradient_norm = std::sqrt(sums[kSetupGradientSq]);
    v->q_norm = sums[kSetupQRowSum];
    v->dual_value = sums[kSetupTraceLambda];
    v->x_norm = std::sqrt(sums[kSetupXNormSq]);
    v->objective_noise = sums[kSetupObjectiveNoise];
    v->poses = static_cast<int>(sums[kSetupDimension]) / (d + 1);
    // The first-order rule of the centralised check: no eigenvalue at a non-critical X.
    CertificateConfig rule;
    rule.eta_relative = settings.eta_relative;
    rule.gradient_tolerance_relative = settings.gradient_tolerance_relative;
    CertificateResult first;
    const bool critical = FirstOrderVerdict(QuantitiesOf(*v), rule, &first);
    v->eta = first.eta;
    v->gradient_tolerance = first.gradient_tolerance;
    return critical;
}

RoundMailbox::RoundMailbox(int robot, std::vector<int> team, std::set<int> neighbor_robots)
    : robot_(robot), team_(std::move(team)), neighbor_robots_(std::move(neighbor_robots)) {}

void RoundMailbox::PutVector(int robot, int step, int current, const std::vector<slam::PoseId>& ids,
                             const Eigen::VectorXd& values) {
    if (step < current || !neighbor_robots_.count(robot)) return;
    vectors_[step][robot] = {ids, values};
}

void RoundMailbox::PutPartial(int robot, int step, int stage, int current,
                              const std::vector<double>& values) {
    if (step < current || robot == robot_) return;
    partials_[{step, stage}][robot] = values;
}

void RoundMailbox::PutOwn(int step, int stage, const std::vector<double>& values) {
    partials_[{step, stage}][robot_] = values;
}

bool RoundMailbox::Reduce(int step, int stage, std::vector<double>* sums,
                          const std::vector<std::size_t>& max_at) {
    const auto it = partials_.find({step, stage});
    if (it == partials_.end() || it->second.size() < team_.size()) return false;
    sums->clear();
    for (const int r : team_) {  // the same order on every robot: the same sums, bit for bit
        const auto p = it->second.find(r);
        if (p == it->second.end()) return false;
        if (sums->empty()) sums->assign(p->second.size(), 0.0);
        if (p->second.size() != sums->size()) return false;
        for (std::size_t i = 0; i < sums->size(); ++i) {
            const bool max = std::find(max_at.begin(), max_at.end(), i) != max_at.end();
            (*sums)[i] = max ? std::max((*sums)[i], p->second[i]) : (*sums)[i] + p->second[i];
        }
    }
    partials_.erase(it);
    return true;
}

std::map<int, NeighborEntries>* RoundMailbox::Vectors(int step) {
    const auto it = vectors_.find(step);
    for (const int r : neighbor_robots_) {
        if (it == vectors_.end() || !it->second.count(r)) return nullptr;
    }
    // No neighbour: an empty entry for the step, so that the caller can proceed.
    return it != vectors_.end() ? &it->second : &vectors_[step];
}

void RoundMailbox::Clear() {
    vectors_.clear();
    partials_.clear();
}

bool GatherNeighborEntries(const LocalCertificateProblem& problem,
                           const std::map<int, NeighborEntries>& vectors, Eigen::Index cols,
                           Eigen::MatrixXd* out) {
    const int b = problem.rows.d + 1;
    out->resize(b * static_cast<Eigen::Index>(problem.neighbor_ids.size()), cols);
    for (std::size_t k = 0; k < problem.neighbor_ids.size(); ++k) {
        const slam::PoseId& id = problem.neighbor_ids[k];
        const auto message = vectors.find(id.robot);
        if (message == vectors.end()) return false;
        const auto& [ids, values] = message->second;
        const auto pos = std::find(ids.begin(), ids.end(), id);
        const Eigen::Index per_column = b * static_cast<Eigen::Index>(ids.size());
        if (pos == ids.end() || values.size() != per_column * cols) return false;
        for (Eigen::Index j = 0; j < cols; ++j) {
            out->block(b * static_cast<Eigen::Index>(k), j, b, 1) =
                values.segment(j * per_column + b * (pos - ids.begin()), b);
        }
    }
    return true;
}

}  // namespace certislam::certify
