// TeamFinish: the trust region of slam::SolveBlockRtr (Steihaug-CG in the preconditioner's norm,
// Manopt's rules) cut at every exchange and every sum, so that a robot runs it from messages.
#include "certify/pipeline/team_finish_impl.h"
#include "slam/backend/stiefel.h"

namespace certislam::certify {

using finish_detail::Inner;
using finish_detail::kBlock;
using finish_detail::kD;
using finish_detail::kFlatSteps;

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
            if (!rows.Build(&at) || (config.overlap > 0 && !domain.Factorize())) Spoil();
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
            return Gathered();
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
            if (FinishRows::Gather(at, by_id, &d_nbr)) {
                Hd = FinishRows::Hessian(at, delta, d_nbr);
            } else {
                Spoil();
                Hd = Eigen::MatrixXd::Zero(at.X.rows(), at.X.cols());
            }
            if (config.overlap > 0) SendDomainEntries(Hd);
            SendSums({Inner(delta, Hd)});
            phase = Phase::kCurvSums;
            return true;
        }
        case Phase::kCurvSums: {
            FinishEntries* in = nullptr;
            if (config.overlap > 0 && (in = Received()) == nullptr) return false;
            if (!Reduced(1, &s)) return false;
            std::map<slam::PoseId, Eigen::MatrixXd> hd_nbr;
            if (in != nullptr) {
                StoreEntries(*in, &hd_nbr);
                vectors.erase(exchange - 1);
            }
            OnCurvSums(s[0], hd_nbr);
            return true;
        }
        case Phase::kCandidate:
            return OnCandidate();
        case Phase::kCandSums:
            if (!Reduced(6, &s)) return false;
            OnCandSums(s);
            return true;
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

bool TeamFinish::Impl::OnCandidate() {
    auto* in = Received();
    if (in == nullptr) return false;
    StoreEntries(*in, &cand.nbr);
    vectors.erase(exchange - 1);
    if (!rows.Build(&cand)) Spoil();
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
    if (m.config.overlap == 0 && !m.domain.Factorize()) m.Spoil();  // the own block alone
    m.Advance();
}

void TeamFinish::OnEdges(int robot, const std::vector<slam::PoseId>& poses,
                         const std::vector<slam::LoopClosure>& edges) {
    Impl& m = *impl_;
    if (!m.neighbours.count(robot) || !m.edges_from.insert(robot).second) return;
    m.domain.Add(robot, poses, edges);
    m.Advance();
}

// A neighbour sends an exchange only with every neighbour's previous one in, so it is at most
// one exchange ahead (the window allows two) and one sum ahead:
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
