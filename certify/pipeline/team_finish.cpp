// TeamFinish: the trust region of slam::SolveBlockRtr (Steihaug-CG in the preconditioner's norm,
// Manopt's rules) cut at every exchange and every sum, so that a robot runs it from messages.
#include "certify/pipeline/team_finish.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

#include "certify/pipeline/team_finish_domain.h"
#include "certify/pipeline/team_finish_rows.h"
#include "slam/backend/stiefel.h"

namespace certislam::certify {
namespace {

constexpr int kBlock = 4;  // d + 1 columns per pose (d = 3)
constexpr int kD = 3;
constexpr int kFlatSteps = 3;  // steps without halving the gradient that make a floor

double Inner(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B) { return A.cwiseProduct(B).sum(); }

}  // namespace

struct TeamFinish::Impl {
    enum class Phase {
        kStartX,     // exchange: the neighbours' entries of the starting X
        kStartSums,  // sum: f, ||grad||^2
        kGather,     // exchange: the neighbours' entries of r on the own domain
        kScatter,    // exchange: the neighbours' shares of z at the own poses
        kPrecSums,   // sum: <r, z>, ||r||^2
        kProduct,    // exchange: the neighbours' entries of delta
        kCurvSums,   // sum: <delta, H delta>
        kCandidate,  // exchange: the neighbours' entries of the candidate X+
        kCandSums,   // sum: f(X+), <grad, eta>, <eta, H eta>, ||grad(X+)||^2, f(X+) - f(X)
        kFailed,     // sum: the one this robot spoiled (Fail), then kInconsistent
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
    double rz = 0.0, alpha = 0.0, e_Pe = 0.0, e_Pd = 0.0, d_Pd = 0.0, stop = 0.0;
    double radius = -1.0, max_radius = 0.0, tol = 0.0;
    int tcg = 0;
    bool initial_prec = true;
    bool hit_boundary_ = false;
    bool started = false;
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
        out_sums.push_back({reduction++, std::move(values)});
        ++progress.reductions;
    }
    // The last exchange's messages once every neighbour's is in.
    FinishEntries* Received() {
        auto it = vectors.find(exchange - 1);
        if (neighbours.empty()) return &vectors[exchange - 1];
        return it != vectors.end() && it->second.size() == neighbours.size() ? &it->second
                                                                             : nullptr;
    }
    // The team's sums of the last reduction, added in team order (the same bits everywhere);
    // a share of another length or not finite (a robot's local failure: Fail) ends every
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
    // A local failure (a neighbour's entries missing, a factor failed): this robot sends the
    // exchange its neighbours still wait for before the next sum (an empty scatter) and a
    // non-finite share of that sum, so that every robot ends there (Reduced).
    void Fail() {
        if (phase == Phase::kGather) {
            std::map<int, Eigen::MatrixXd> blocks;
            for (int j : neighbours) blocks[j] = Eigen::MatrixXd(at.X.rows(), 0);
            SendEach(blocks, {});
        }
        SendSums({std::numeric_limits<double>::quiet_NaN()});
        phase = Phase::kFailed;
    }

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
    bool Scatter();
    bool ApplyScatter();
    void OnPrecSums(const std::vector<double>& s);
    void OnCurvSums(double dHd);
    void EndTcg();
    bool OnCandidate();
    void OnCandSums(const std::vector<double>& s);
};

void TeamFinish::Impl::Advance() {
    while (started && phase != Phase::kDone && Step()) {
    }
}

// One transition of the phase machine; false when a message is missing.
bool TeamFinish::Impl::Step() {
    std::vector<double> s;
    switch (phase) {
        case Phase::kStartX: {
            auto* in = Received();
            if (in == nullptr || (config.overlap > 0 && edges_from.size() < neighbours.size()))
                return false;
            StoreEntries(*in, &at.nbr);
            vectors.erase(exchange - 1);
            if (!rows.Build(&at) || (config.overlap > 0 && !domain.Factorize())) {
                Fail();
                return true;
            }
            SendSums({at.problem.cost, at.grad.squaredNorm()});
            phase = Phase::kStartSums;
            return true;
        }
        case Phase::kStartSums:
            if (!Reduced(2, &s)) return false;
            f = s[0];
            g = std::sqrt(std::max(s[1], 0.0));
            BeginIteration();
            return true;
        case Phase::kGather:
            return Scatter();
        case Phase::kScatter:
            return ApplyScatter();
        case Phase::kPrecSums:
            if (!Reduced(2, &s)) return false;
            OnPrecSums(s);
            return true;
        case Phase::kProduct: {
            auto* in = Received();
            if (in == nullptr) return false;
            std::map<slam::PoseId, Eigen::MatrixXd> by_id;
            StoreEntries(*in, &by_id);
            vectors.erase(exchange - 1);
            Eigen::MatrixXd d_nbr;
            if (!FinishRows::Gather(at, by_id, &d_nbr)) {
                Fail();
                return true;
            }
            Hd = FinishRows::Hessian(at, delta, d_nbr);
            SendSums({Inner(delta, Hd)});
            phase = Phase::kCurvSums;
            return true;
        }
        case Phase::kCurvSums:
            if (!Reduced(1, &s)) return false;
            OnCurvSums(s[0]);
            return true;
        case Phase::kCandidate:
            return OnCandidate();
        case Phase::kCandSums:
            if (!Reduced(6, &s)) return false;
            OnCandSums(s);
            return true;
        case Phase::kFailed:
            Reduced(1, &s);  // never succeeds: this robot's own share is not finite
            return false;
        case Phase::kDone:
            return false;
    }
    return false;
}

void TeamFinish::Impl::BeginIteration() {
    progress.cost = f;
    progress.grad_norm = g;
    tol = config.rel_grad_tol * std::max(1.0, f);
    if (g <= tol) return Finish(Status::kConverged);
    // At the floor of what doubles resolve on an ill-conditioned graph (parking-garage): the
    // gradient stopped halving, below the tolerance the centralised solver stops at.
    if (g <= config.floor_rel_grad_tol * std::max(1.0, f) && flat_steps >= kFlatSteps) {
        progress.at_floor = true;
        return Finish(Status::kConverged);
    }
    if (progress.iterations >= config.max_iterations || (radius >= 0.0 && radius <= 1e-14))
        return Finish(Status::kNotConverged);
    ++progress.iterations;
    r = at.grad;
    eta = Eigen::MatrixXd::Zero(at.X.rows(), at.X.cols());
    Heta = eta;
    tcg = 0;
    initial_prec = true;
    StartPrecondition();
}

// z = Proj(P^{-1} r): block Jacobi locally, or the domain's solve between two exchanges.
void TeamFinish::Impl::StartPrecondition() {
    if (config.overlap == 0) {
        z = slam::ProjectToTangent(at.X, domain.Solve(r), kD);
        SendSums({Inner(r, z), r.squaredNorm()});
        phase = Phase::kPrecSums;
        return;
    }
    std::map<int, Eigen::MatrixXd> blocks;
    std::map<int, std::vector<slam::PoseId>> ids;
    for (int j : neighbours) {
        ids[j] = domain.OwnPosesIn(j);
        blocks[j] = OwnColumns(r, ids[j]);
    }
    SendEach(blocks, ids);
    phase = Phase::kGather;
}

bool TeamFinish::Impl::Scatter() {
    auto* in = Received();
    if (in == nullptr) return false;
    std::map<slam::PoseId, Eigen::MatrixXd> by_id;
    StoreEntries(*in, &by_id);
    vectors.erase(exchange - 1);
    std::map<int, std::vector<slam::PoseId>> ids;
    std::map<int, Eigen::MatrixXd> blocks;
    for (int j : neighbours) ids[j];
    if (!domain.Solve(r, by_id, &z, &ids, &blocks)) {
        Fail();
        return true;
    }
    SendEach(blocks, ids);
    phase = Phase::kScatter;
    return true;
}

bool TeamFinish::Impl::ApplyScatter() {
    auto* in = Received();
    if (in == nullptr) return false;
    if (!domain.AddReturned(*in, &z)) {
        Fail();
        return true;
    }
    vectors.erase(exchange - 1);
    z = slam::ProjectToTangent(at.X, z, kD);
    SendSums({Inner(r, z), r.squaredNorm()});
    phase = Phase::kPrecSums;
    return true;
}

void TeamFinish::Impl::OnPrecSums(const std::vector<double>& s) {
    const double rz_new = s[0];
    const double r_norm = std::sqrt(std::max(s[1], 0.0));
    if (initial_prec) {
        initial_prec = false;
        if (radius < 0.0) {  // the preconditioned gradient's size, about the Newton step's
            radius = std::sqrt(std::max(rz_new, 0.0));
            max_radius = 1e3 * std::max(radius, 1e-12);
        }
        stop = std::max(r_norm * std::min(r_norm, 0.1), config.tcg_residual_floor * tol);
        rz = rz_new;
        delta = -z;
        e_Pe = e_Pd = 0.0;
        d_Pd = rz;
    } else {
        if (r_norm <= stop || tcg >= config.max_tcg_iterations) return EndTcg();
        const double beta = rz_new / rz;
        rz = rz_new;
        delta = -z + beta * delta;
        e_Pd = beta * (e_Pd + alpha * d_Pd);
        d_Pd = rz + beta * beta * d_Pd;
    }
    SendRead(delta, false);
    phase = Phase::kProduct;
}

void TeamFinish::Impl::OnCurvSums(double dHd) {
    ++tcg;
    ++progress.tcg_iterations;
    alpha = rz / dHd;
    const double e_Pe_new = e_Pe + 2.0 * alpha * e_Pd + alpha * alpha * d_Pd;
    if (dHd <= 0.0 || e_Pe_new >= radius * radius) {  // to the boundary along delta
        const double tau = SteihaugToBoundary(e_Pe, e_Pd, d_Pd, radius);
        eta += tau * delta;
        Heta += tau * Hd;
        hit_boundary_ = true;
        return EndTcg();
    }
    e_Pe = e_Pe_new;
    eta += alpha * delta;
    Heta += alpha * Hd;
    r = slam::ProjectToTangent(at.X, r + alpha * Hd, kD);
    StartPrecondition();
}

void TeamFinish::Impl::EndTcg() {
    cand = FinishPoint{};
    cand.X = slam::Retract(at.X, eta, kD);
    SendRead(cand.X, true);
    phase = Phase::kCandidate;
}

bool TeamFinish::Impl::OnCandidate() {
    auto* in = Received();
    if (in == nullptr) return false;
    StoreEntries(*in, &cand.nbr);
    vectors.erase(exchange - 1);
    if (!rows.Build(&cand)) {
        Fail();
        return true;
    }
    const auto [change, change_noise] = rows.CostChange(at, cand);
    SendSums({cand.problem.cost, Inner(at.grad, eta), Inner(eta, Heta), cand.grad.squaredNorm(),
              change, change_noise});
    phase = Phase::kCandSums;
    return true;
}

void TeamFinish::Impl::OnCandSums(const std::vector<double>& s) {
    const double change = s[4];  // measured directly (CostChange), not f(X+) - f(X)
    const double model = -s[1] - 0.5 * s[2];
    const double g_new = std::sqrt(std::max(s[3], 0.0));
    // Manopt's rho regularisation, and the change's own rounding bound.
    const double reg = std::max(
        1e3 * std::numeric_limits<double>::epsilon() * std::max(1.0, std::abs(f)), 10.0 * s[5]);
    const double rho = (-change + reg) / (model + reg);
    if (rho < 0.25) {
        radius *= 0.25;
    } else if (rho > 0.75 && hit_boundary_) {
        radius = std::min(2.0 * radius, max_radius);
    }
    hit_boundary_ = false;
    // Where f's decrease is below its rounding the gradient decides: a step that does not
    // lower it is not taken (f alone would accept every step at the floor).
    const bool measurable = -change > reg;
    if (rho > 0.1 && change <= reg && (measurable || g_new < g)) {
        at = std::move(cand);
        f = s[0];
        g = g_new;
        ++progress.accepted;
    }
    flat_steps = g < 0.5 * best_g ? 0 : flat_steps + 1;
    best_g = std::min(best_g, g);
    BeginIteration();
}

TeamFinish::TeamFinish(int robot, std::vector<int> team, const Eigen::MatrixXd& X_own,
                       std::vector<slam::LoopClosure> edges, TeamFinishConfig config)
    : impl_(std::make_unique<Impl>(robot, std::move(team), X_own, std::move(edges), config)) {}
TeamFinish::~TeamFinish() = default;
TeamFinish::TeamFinish(TeamFinish&&) noexcept = default;
TeamFinish& TeamFinish::operator=(TeamFinish&&) noexcept = default;

void TeamFinish::Start() {
    Impl& m = *impl_;
    if (m.config.overlap > 0) {
        for (int j : m.neighbours) {
            m.out_edges.push_back({j, m.domain.OwnPosesIn(j), m.domain.EdgesFor(j)});
        }
    }
    m.SendRead(m.at.X, true);
    m.phase = Impl::Phase::kStartX;
    m.started = true;
    if (m.config.overlap == 0 && !m.domain.Factorize()) return m.Fail();  // the own block alone
    m.Advance();
}

void TeamFinish::OnEdges(int robot, const std::vector<slam::PoseId>& poses,
                         const std::vector<slam::LoopClosure>& edges) {
    Impl& m = *impl_;
    if (!m.neighbours.count(robot) || !m.edges_from.insert(robot).second) return;
    m.domain.Add(robot, poses, edges);
    m.Advance();
}

// A neighbour is at most two exchanges ahead (gather and scatter before a sum) and one sum ahead:
// anything further, older, repeated, of another rank, not finite, or naming a pose of a third
// robot is dropped (counted), so a peer cannot grow the mailboxes or overwrite others' poses.
void TeamFinish::OnVector(int robot, std::uint64_t step, const std::vector<slam::PoseId>& ids,
                          const Eigen::MatrixXd& blocks) {
    Impl& m = *impl_;
    const bool in_window = step + 1 >= m.exchange && step <= m.exchange + 2;
    const bool shaped = blocks.cols() == kBlock * Eigen::Index(ids.size()) &&
                        (blocks.cols() == 0 || blocks.rows() == m.at.X.rows()) &&
                        blocks.allFinite();
    const bool owned = std::all_of(ids.begin(), ids.end(), [&](const slam::PoseId& id) {
        return id.robot == robot || id.robot == m.robot;
    });
    if (!m.neighbours.count(robot) || !in_window || !shaped || !owned ||
        m.vectors[step].count(robot) > 0) {
        ++m.progress.dropped;
        return;
    }
    m.vectors[step][robot] = {ids, blocks};
    m.Advance();
}

void TeamFinish::OnSums(int robot, std::uint64_t step, const std::vector<double>& values) {
    Impl& m = *impl_;
    const bool member = std::find(m.team.begin(), m.team.end(), robot) != m.team.end();
    const bool in_window = step + 1 >= m.reduction && step <= m.reduction + 1;
    if (!member || !in_window || m.sums[step].count(robot) > 0) {
        ++m.progress.dropped;
        return;
    }
    m.sums[step][robot] = values;
    m.Advance();
}

std::vector<FinishEdges> TeamFinish::TakeEdges() { return std::exchange(impl_->out_edges, {}); }
std::vector<FinishVector> TeamFinish::TakeVectors() {
    return std::exchange(impl_->out_vectors, {});
}
std::vector<FinishSums> TeamFinish::TakeSums() { return std::exchange(impl_->out_sums, {}); }
TeamFinish::Status TeamFinish::status() const { return impl_->status; }
const Eigen::MatrixXd& TeamFinish::Block() const { return impl_->at.X; }
PoseBlocks TeamFinish::NeighbourPoses() const {
    return BlocksOf(impl_->at.nbr, impl_->at.X.rows());
}
const TeamFinishProgress& TeamFinish::Progress() const { return impl_->progress; }
const std::set<int>& TeamFinish::Neighbours() const { return impl_->neighbours; }

}  // namespace certislam::certify
