// Certifier, distributed mode: the anchor opens rounds; every certifier builds its rows of S from
// the named bundles and runs its share of Lanczos over CertificateVector/CertificateReduction.
#include <chrono>
#include <iterator>
#include <set>

#include "actors/certifier_actor.h"
#include "certify/saddle_escape.h"
#include "slam/backend/connection_laplacian.h"

namespace certislam::actors {
namespace {

constexpr std::size_t kMaxEarlyMessages = 100000;  ///< buffered messages of rounds not begun
constexpr int kBlock = 4;                          ///< columns per pose (d + 1, d = 3)

v1::CertificateVerdict VerdictOf(DistributedVerdict::Status status) {
    switch (status) {
        case DistributedVerdict::Status::kCertified:
            return v1::CERTIFICATE_VERDICT_CERTIFIED;
        case DistributedVerdict::Status::kNotCertified:
            return v1::CERTIFICATE_VERDICT_NOT_CERTIFIED;
        default:
            return v1::CERTIFICATE_VERDICT_INCONCLUSIVE;
    }
}

/// Keeps the round's opening (anchor), this robot's last vector and its last two partial sums
/// (a peer that lost the second pass's sums of step k waits for them while this robot waits for
/// the peer's first-pass sums of step k + 1).
void Remember(std::vector<transport::Message>* sent, transport::Message m) {
    constexpr int kReductionsKept = 2;
    if (m.Is<v1::CertificateVector>()) {
        std::erase_if(
            *sent, [](const transport::Message& old) { return old.Is<v1::CertificateVector>(); });
    } else {
        int kept = 0;
        for (auto it = sent->rbegin(); it != sent->rend(); ++it) {
            if (it->Is<v1::CertificateReduction>()) ++kept;
            if (kept == kReductionsKept) {
                sent->erase(std::next(it).base());
                break;
            }
        }
    }
    sent->push_back(std::move(m));
}

}  // namespace

std::optional<DistributedVerdict> CertifierActor::LastVerdict() const {
    std::lock_guard lock(verdict_mutex_);
    return verdict_;
}

void CertifierActor::SubscribeRounds() {
    for (int r : Wiring().robots) {
        if (r != RobotId()) OpenClient(Edge::kCertify, r);
    }
    On(v1::CertificateRound::descriptor()->full_name(), [this](const transport::Message& m) {
        const auto round = transport::Unpack<v1::CertificateRound>(m);
        if (!round) return false;
        OnRound(*round);
        return true;
    });
    for (const auto* type :
         {v1::CertificateVector::descriptor(), v1::CertificateReduction::descriptor()}) {
        On(type->full_name(), [this](const transport::Message& m) {
            Deliver(m);
            return true;
        });
    }
}

void CertifierActor::StartRound() {
    v1::CertificateRound round;
    *round.mutable_header() = MakeHeader(RobotId(), NextSequence(), 0);
    // Unique across anchor restarts: wall-clock milliseconds, then a counter.
    const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(
                        std::chrono::system_clock::now().time_since_epoch())
                        .count();
    round.set_round(static_cast<std::uint64_t>(ms) * 1000 + (++rounds_opened_ % 1000));
    round.set_rank_r(static_cast<std::uint32_t>(bundles_.begin()->second.block.blocks.rows()));
    std::map<int, std::set<int>> neighbors;  // robots sharing an edge
    for (const auto& [robot, b] : bundles_) {
        for (const auto& e : b.edges) {
            if (e.a.robot == e.b.robot) continue;
            neighbors[e.a.robot].insert(e.b.robot);
            neighbors[e.b.robot].insert(e.a.robot);
        }
    }
    for (const auto& [robot, b] : bundles_) {
        auto* ref = round.add_bundles();
        ref->set_robot_id(static_cast<std::uint32_t>(robot));
        ref->set_digest(b.digest);
        for (int n : neighbors[robot]) ref->add_neighbors(static_cast<std::uint32_t>(n));
    }
    Send(*out_, transport::Pack(round), true);
    round_opened_ = std::chrono::steady_clock::now();
    OnRound(round);
    round_sent_.insert(round_sent_.begin(), transport::Pack(round));
}

void CertifierActor::OnRound(const v1::CertificateRound& round) {
    if (lanczos_ && round.round() == round_) return;  // a re-sent opening
    // The anchor uses every bundle; the others their own and their neighbours' (read from now on).
    std::set<int> needed;
    for (const auto& ref : round.bundles()) {
        if (int(ref.robot_id()) != RobotId()) continue;
        needed.insert(RobotId());
        for (const auto n : ref.neighbors()) needed.insert(int(n));
    }
    for (int r : needed) ReadBundlesOf(r);
    std::map<int, const Bundle*> chosen;
    for (const auto& ref : round.bundles()) {
        if (!anchor_ && !needed.count(int(ref.robot_id()))) continue;
        const Bundle* b = nullptr;
        for (const auto& candidate : history_[int(ref.robot_id())]) {
            if (candidate.digest == ref.digest()) b = &candidate;
        }
        if (b == nullptr) {  // not here yet (or never: the anchor will open another round)
            waiting_ = round;
            return;
        }
        chosen[int(ref.robot_id())] = b;
    }
    waiting_.reset();
    if (!chosen.count(RobotId())) return;
    const Bundle& own = *chosen.at(RobotId());
    std::vector<slam::LoopClosure> edges;
    std::map<slam::PoseId, Eigen::MatrixXd> far;
    round_edges_ = 0;
    for (const auto& [robot, b] : chosen) {
        round_edges_ += b->edges.size();
        for (const auto& e : b->edges) {
            if (e.a.robot != RobotId() && e.b.robot != RobotId()) continue;
            edges.push_back(e);
            for (const slam::PoseId& id : {e.a, e.b}) {
                const auto it = chosen.find(id.robot);
                if (id.robot == RobotId() || it == chosen.end()) continue;
                const auto& blocks = it->second->block.blocks;
                if (kBlock * (id.index + 1) <= blocks.cols()) {
                    far[id] = blocks.middleCols(kBlock * id.index, kBlock);
                }
            }
        }
    }
    LocalCertificateProblem problem;
    if (!MakeLocalProblem(RobotId(), own.block.ids, own.block.blocks, edges, far, &problem)) {
        return;  // a far end outside its robot's block: the anchor retries with newer bundles
    }
    round_ = round.round();
    round_rank_ = round.rank_r();
    round_bundles_.clear();
    if (anchor_) {  // its report, a cross-check and an escape are about this round's graph
        for (const auto& [robot, b] : chosen) round_bundles_[robot] = *b;
    }
    round_progress_ = std::chrono::steady_clock::now();
    round_heard_ = false;
    round_sent_.clear();
    const auto send_vector = [this](int step, const std::vector<slam::PoseId>& ids,
                                    const Eigen::VectorXd& values) {
        v1::CertificateVector v;
        *v.mutable_header() = MakeHeader(RobotId(), NextSequence(), 0);
        v.set_round(round_);
        v.set_step(static_cast<std::uint32_t>(step));
        v.set_block_size(kBlock);
        for (const auto& id : ids) *v.add_pose_ids() = ToProto(id);
        v.mutable_values()->Add(values.data(), values.data() + values.size());
        Send(*out_, transport::Pack(v), true);
        Remember(&round_sent_, transport::Pack(v));
    };
    const auto send_reduction = [this](int step, int stage, const std::vector<double>& values) {
        v1::CertificateReduction r;
        *r.mutable_header() = MakeHeader(RobotId(), NextSequence(), 0);
        r.set_round(round_);
        r.set_step(static_cast<std::uint32_t>(step));
        r.set_stage(static_cast<std::uint32_t>(stage));
        r.mutable_values()->Add(values.begin(), values.end());
        Send(*out_, transport::Pack(r), true);
        Remember(&round_sent_, transport::Pack(r));
    };
    lanczos_ = std::make_unique<LanczosParticipant>(std::move(problem), Wiring().robots, round_,
                                                    config_.lanczos, send_vector, send_reduction);
    lanczos_->Begin();
    auto early = std::move(early_[round_]);
    early_.clear();
    for (const auto& m : early) Deliver(m);
    RoundFinished();
}

void CertifierActor::Deliver(const transport::Message& m) {
    std::uint64_t round = 0;
    const auto vector =
        m.Is<v1::CertificateVector>() ? transport::Unpack<v1::CertificateVector>(m) : std::nullopt;
    const auto reduction = m.Is<v1::CertificateReduction>()
                               ? transport::Unpack<v1::CertificateReduction>(m)
                               : std::nullopt;
    if (vector) round = vector->round();
    if (reduction) round = reduction->round();
    if (round == 0) return;
    if (round != round_ || !lanczos_) {
        std::size_t buffered = 0;
        for (const auto& [id, list] : early_) buffered += list.size();
        if (buffered < kMaxEarlyMessages) early_[round].push_back(m);
        return;
    }
    if (lanczos_->Done()) return;
    round_progress_ = std::chrono::steady_clock::now();
    round_heard_ = true;
    if (vector) {
        std::vector<slam::PoseId> ids;
        for (const auto& id : vector->pose_ids()) {
            const auto pose = FromProto(id);
            if (!pose) return;
            ids.push_back(*pose);
        }
        const Eigen::VectorXd values = Eigen::Map<const Eigen::VectorXd>(
            vector->values().data(), static_cast<Eigen::Index>(vector->values_size()));
        lanczos_->OnVector(int(vector->header().robot_id()), int(vector->step()), ids, values);
    } else {
        lanczos_->OnReduction(int(reduction->header().robot_id()), int(reduction->step()),
                              int(reduction->stage()),
                              {reduction->values().begin(), reduction->values().end()});
    }
    RoundFinished();
}

void CertifierActor::ResendIfStalled() {
    const auto now = std::chrono::steady_clock::now();
    if (!lanczos_ || lanczos_->Done() || now - round_progress_ < config_.round_resend ||
        now - round_resent_ < config_.round_resend) {
        return;
    }
    // Receivers take a message twice without harm (the same values overwrite the same slot).
    for (const auto& m : round_sent_) Send(*out_, m, true);
    round_resent_ = now;
}

void CertifierActor::RoundFinished() {
    if (!lanczos_ || !lanczos_->Done()) return;
    DistributedVerdict verdict = lanczos_->Verdict();
    {
        std::lock_guard lock(verdict_mutex_);
        if (verdict_ && verdict_->round == verdict.round) return;  // already counted
    }
    slam::PoseGraph graph;
    Eigen::MatrixXd X;
    const bool assembled =
        anchor_ &&
        (config_.cross_check || verdict.status == DistributedVerdict::Status::kNotCertified) &&
        Assemble(round_bundles_, &graph, &X);
    std::optional<certify::CertificateResult> central;
    if (assembled && config_.cross_check) {
        central = certify::Certify(slam::ConnectionLaplacian(graph), X, 3, config_.certificate);
        verdict.central_lambda_min = central->lambda_min;
    }
    {
        std::lock_guard lock(verdict_mutex_);
        verdict_ = verdict;
    }
    ++rounds_;
    ++checks_;
    lanczos_steps_ += static_cast<std::uint64_t>(verdict.steps);
    if (!anchor_) return;
    NoteVerdict(verdict.status == DistributedVerdict::Status::kCertified, round_bundles_);
    v1::CertificateReport report;
    *report.mutable_header() = MakeHeader(RobotId(), NextSequence(), 0);
    report.set_verdict(VerdictOf(verdict.status));
    report.set_lambda_min(verdict.lambda_min);
    report.set_eps_tolerance(verdict.eta);
    report.set_duality_gap(verdict.cost - verdict.dual_value);
    report.set_objective(verdict.cost);
    report.set_rank_r(round_rank_);
    report.set_iteration(round_edges_);  // which graph: its edge count
    report.set_path(v1::CERTIFICATE_PATH_DISTRIBUTED);
    Send(*out_, transport::Pack(report), true);
    if (verdict.status != DistributedVerdict::Status::kNotCertified ||
        level_ >= config_.max_staircase_steps || !assembled) {
        return;
    }
    // The escape stays centralised: the anchor computes the eigenvector on the round's graph.
    const auto Q = slam::ConnectionLaplacian(graph);
    if (!central) central = certify::Certify(Q, X, 3, config_.certificate);
    if (central->status == certify::CertificateResult::Status::kNotOptimal) {
        Escape(Q, X, central->eigenvector, central->gradient_tolerance, round_bundles_);
    }
}

}  // namespace certislam::actors
