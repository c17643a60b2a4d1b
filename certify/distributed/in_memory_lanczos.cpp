// A team of LanczosParticipants whose messages are delivered in memory: the distributed
// eigenvalue check over plain data (tests, benchmarks and the pipeline).
#include <Eigen/Dense>
#include <cmath>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <set>

#include "certify/distributed/distributed_lanczos.h"
#include "slam/core/check.h"

namespace certislam::certify {

namespace {

using Segments = std::vector<Eigen::VectorXd>;

double Dot(const Segments& a, const Segments& b) {
    double s = 0.0;
    for (size_t k = 0; k < a.size(); ++k) s += a[k].dot(b[k]);
    return s;
}

/// The exact product S v over the team (for the residual of the final Ritz vector).
Segments Multiply(const std::vector<LocalCertificateProblem>& problems, const Segments& v) {
    std::map<slam::PoseId, Eigen::VectorXd> published;
    for (size_t k = 0; k < problems.size(); ++k) {
        const int b = problems[k].rows.d + 1;
        const Eigen::VectorXd entries = PublicEntries(problems[k].rows, v[k]);
        for (size_t p = 0; p < problems[k].public_ids.size(); ++p) {
            published[problems[k].public_ids[p]] = entries.segment(b * p, b);
        }
    }
    Segments out(problems.size());
    for (size_t k = 0; k < problems.size(); ++k) {
        const int b = problems[k].rows.d + 1;
        Eigen::VectorXd nbr(b * static_cast<Eigen::Index>(problems[k].neighbor_ids.size()));
        for (size_t p = 0; p < problems[k].neighbor_ids.size(); ++p) {
            nbr.segment(b * p, b) = published.at(problems[k].neighbor_ids[p]);
        }
        out[k] = MultiplyRows(problems[k].rows, v[k], nbr);
    }
    return out;
}

}  // namespace

std::vector<LocalCertificateProblem> LocalProblemsOf(const std::vector<CertificateRows>& robots) {
    std::map<int, int> owner;  // public global pose -> robot
    for (size_t k = 0; k < robots.size(); ++k) {
        for (const int g : robots[k].public_poses) owner[g] = static_cast<int>(k);
    }
    std::vector<LocalCertificateProblem> problems(robots.size());
    for (size_t k = 0; k < robots.size(); ++k) {
        LocalCertificateProblem& p = problems[k];
        p.robot = static_cast<int>(k);
        p.rows = robots[k];
        for (const int g : p.rows.public_poses) p.public_ids.push_back({p.robot, g});
        for (const int g : p.rows.neighbor_poses) {
            const auto it = owner.find(g);
            CERTISLAM_CHECK(it != owner.end());  // every neighbour pose is public at its owner
            p.neighbor_ids.push_back({it->second, g});
            p.neighbor_robots.insert(it->second);
        }
    }
    return problems;
}

std::vector<std::unique_ptr<RoundParticipant>> RunInMemory(
    const std::vector<LocalCertificateProblem>& problems, const LanczosSettings& settings,
    InMemoryTraffic* traffic) {
    InMemoryTraffic ignored;
    InMemoryTraffic& count = traffic != nullptr ? *traffic : ignored;
    std::vector<int> team;
    std::map<int, size_t> slot;  // robot id -> index
    for (size_t k = 0; k < problems.size(); ++k) {
        team.push_back(problems[k].robot);
        slot[problems[k].robot] = k;
    }
    std::deque<std::function<void()>> mail;  // deliveries in send order
    std::vector<std::unique_ptr<RoundParticipant>> robot(problems.size());
    for (size_t k = 0; k < problems.size(); ++k) {
        const int from = problems[k].robot;
        auto send_vector = [&, from](int step, const std::vector<slam::PoseId>& ids,
                                     const Eigen::VectorXd& values) {
            count.exchanges.insert({step, 0});
            count.entries += static_cast<double>(values.size());
            for (size_t to = 0; to < problems.size(); ++to) {
                if (!problems[to].neighbor_robots.count(from)) continue;
                mail.push_back([&, to, from, step, ids, values] {
                    robot[to]->OnVector(from, step, ids, values);
                });
            }
        };
        auto send_reduction = [&, from](int step, int stage, const std::vector<double>& values) {
            count.reductions.insert({step, stage});
            for (size_t to = 0; to < problems.size(); ++to) {
                if (problems[to].robot == from) continue;
                mail.push_back([&, to, from, step, stage, values] {
                    robot[to]->OnReduction(from, step, stage, values);
                });
            }
        };
        robot[k] =
            MakeRoundParticipant(problems[k], team, 0, settings, send_vector, send_reduction);
    }
    for (auto& r : robot) r->Begin();
    while (!mail.empty()) {
        const auto deliver = std::move(mail.front());
        mail.pop_front();
        deliver();
    }
    return robot;
}

DistributedEigenResult DistributedMinEigenpair(const std::vector<CertificateRows>& robots,
                                               const LanczosSettings& settings) {
    settings.Validate();
    CERTISLAM_CHECK(!robots.empty());
    const std::vector<LocalCertificateProblem> problems = LocalProblemsOf(robots);
    DistributedEigenResult result;
    InMemoryTraffic traffic;
    LanczosSettings lanczos = settings;
    lanczos.method = LanczosSettings::Method::kLanczos;  // the counts below are Lanczos'
    const auto robot = RunInMemory(problems, lanczos, &traffic);
    result.entries_exchanged = traffic.entries;
    const DistributedVerdict& verdict = robot.front()->Verdict();
    CERTISLAM_CHECK(verdict.status != DistributedVerdict::Status::kInconsistent);
    result.status = verdict.status == DistributedVerdict::Status::kNotConverged
                        ? DistributedEigenResult::Status::kNotConverged
                        : DistributedEigenResult::Status::kConverged;
    result.steps = verdict.steps;
    Segments v(robots.size());
    for (size_t k = 0; k < robots.size(); ++k) v[k] = robot[k]->RitzSegment();
    const double norm = std::sqrt(Dot(v, v));
    for (auto& s : v) s /= norm;
    Segments Sv = Multiply(problems, v);
    for (const auto& p : problems) {
        result.entries_exchanged += (p.rows.d + 1.0) * static_cast<double>(p.public_ids.size());
    }
    result.lambda_min = Dot(v, Sv);
    for (size_t k = 0; k < v.size(); ++k) Sv[k] -= result.lambda_min * v[k];
    result.residual = std::sqrt(Dot(Sv, Sv));
    result.products = result.steps + 1;
    result.vector_exchanges = static_cast<int>(traffic.exchanges.size()) + 1;
    result.scalar_reductions =
        static_cast<int>(traffic.reductions.size()) + 3;  // ||v||, v^T S v, ||r||
    result.vector = std::move(v);
    return result;
}

}  // namespace certislam::certify
