// Certifier: bundles in; centrally (joint Q and X at the anchor) or as a distributed round
// (every robot's rows of S, certify/distributed); report out, escape blocks out.
#include "actors/certifier_actor.h"

#include <algorithm>
#include <chrono>
#include <set>
#include <stdexcept>

#include "certify/distributed/round_certificate.h"
#include "certify/saddle_escape.h"
#include "slam/backend/connection_laplacian.h"
#include "slam/core/loop_closure.h"
#include "slam/core/pose_graph.h"

namespace certislam::actors {

void CertifierConfig::Validate() const {
    certificate.Validate();
    if (max_staircase_steps < 0) {
        throw std::invalid_argument("CertifierConfig.max_staircase_steps = " +
                                    std::to_string(max_staircase_steps) + ": must be >= 0");
    }
    if (period.count() <= 0) throw std::invalid_argument("CertifierConfig.period: must be > 0");
    if (round_timeout.count() <= 0) {
        throw std::invalid_argument("CertifierConfig.round_timeout: must be > 0");
    }
    if (!(settled_move_relative >= 0.0)) {
        throw std::invalid_argument("CertifierConfig.settled_move_relative = " +
                                    std::to_string(settled_move_relative) + ": must be >= 0");
    }
    try {
        lanczos.Validate();
    } catch (const std::invalid_argument& e) {
        throw std::invalid_argument(std::string("CertifierConfig.lanczos: ") + e.what());
    }
}

namespace {

constexpr std::size_t kHistory = 16;               ///< distinct bundles kept per robot for rounds
constexpr std::size_t kMaxEarlyMessages = 100000;  ///< buffered messages of rounds not begun

}  // namespace

bool CertifierActor::SettledSinceCertified() const {
    // The certified round proved f* >= tr(Lambda) - eta d n for its graph; that bound holds for
    // any X on the same graph, and a block within a small relative move of the certified one
    // changes f by at most 2 ||X Q|| ||dX|| + ||Q|| ||dX||^2: no new round is worth its bytes.
    // A new edge, a withdrawn one, a new pose, a new rank (escape) or a larger move re-checks,
    // and so does a new round session (a robot restarted: it heard no report of the old one).
    if (certified_bundles_.empty() || certified_bundles_.size() != bundles_.size()) return false;
    for (const auto& [robot, b] : bundles_) {
        const auto it = certified_bundles_.find(robot);
        if (it == certified_bundles_.end()) return false;
        const Bundle& c = it->second;
        if (b.status.phase() != c.status.phase() ||
            b.status.round_session() != c.status.round_session() ||
            GraphDigest(b) != GraphDigest(c) || b.block.blocks.rows() != c.block.blocks.rows() ||
            b.block.blocks.cols() != c.block.blocks.cols()) {
            return false;
        }
        const double moved = (b.block.blocks - c.block.blocks).norm();
        if (moved > config_.settled_move_relative * c.block.blocks.norm()) return false;
    }
    return true;
}

void CertifierActor::NoteVerdict(bool certified, const std::map<int, Bundle>& bundles) {
    certified_bundles_.clear();
    if (certified) certified_bundles_ = bundles;
}

CertifierActor::CertifierActor(zmq::context_t& context, TeamWiring wiring, CertifierConfig config)
    : NodeActor("certifier", context, std::move(wiring)), config_(config) {
    // One first-order rule: a round stops before Lanczos exactly where the certificate would.
    config_.lanczos.eta_relative = config_.certificate.eta_relative;
    config_.lanczos.gradient_tolerance_relative = config_.certificate.gradient_tolerance_relative;
    config_.Validate();
}

void CertifierActor::OnStart() {
    out_ = &OpenServer(Edge::kCertify);
    anchor_ = RobotId() == *std::min_element(Wiring().robots.begin(), Wiring().robots.end());
    if (anchor_ || config_.distributed) SubscribeBundles();
    if (config_.distributed) SubscribeRounds();
    Every(config_.period, [this] { Tick(); });
}

void CertifierActor::ReadBundlesOf(int robot) {
    if (bundle_streams_.insert(robot).second) OpenClient(Edge::kBundle, robot);
}

void CertifierActor::SubscribeBundles() {
    // The anchor reads every robot's bundles (it names them in rounds and checks centrally when
    // a round falls silent); in distributed mode the others read their own and, once a round
    // names them, their neighbours' (ReadBundlesOf in OnRound).
    for (int r : Wiring().robots) {
        if (anchor_ || r == RobotId()) ReadBundlesOf(r);
    }
    const auto count = [this](const transport::Message& m, std::uint32_t robot) {
        if (int(robot) != RobotId()) {
            bundle_bytes_.fetch_add(m.ByteSize());
            CountPeerBytes(m.ByteSize());
        }
    };
    On(v1::SolverStatus::descriptor()->full_name(), [this, count](const transport::Message& m) {
        const auto status = transport::Unpack<v1::SolverStatus>(m);
        if (!status || !IsValidStatus(*status)) return false;
        count(m, status->header().robot_id());
        pending_[int(status->header().robot_id())] = Bundle{*status, {}, {}, 0};
        return true;
    });
    On(v1::TrajectoryUpdate::descriptor()->full_name(), [count](const transport::Message& m) {
        const auto update = transport::Unpack<v1::TrajectoryUpdate>(m);
        if (!update) return false;
        count(m, update->header().robot_id());  // closes a bundle; the certifier needs none
        return true;
    });
    On(v1::LoopClosure::descriptor()->full_name(), [this, count](const transport::Message& m) {
        const auto proto = transport::Unpack<v1::LoopClosure>(m);
        const auto edge = proto ? FromProto(*proto) : std::nullopt;
        if (!edge) return false;
        count(m, proto->header().robot_id());
        const auto it = pending_.find(int(proto->header().robot_id()));
        if (it != pending_.end()) it->second.edges.push_back(*edge);
        return true;
    });
    On(v1::PublicPoses::descriptor()->full_name(), [this, count](const transport::Message& m) {
        const auto proto = transport::Unpack<v1::PublicPoses>(m);
        auto block = proto ? FromProto(*proto) : std::nullopt;
        const int robot = proto ? int(proto->header().robot_id()) : -1;
        if (!block) return false;
        const auto it = pending_.find(robot);
        if (it == pending_.end()) return true;  // joined mid-bundle (or an escape): wait
        count(m, proto->header().robot_id());
        it->second.block = std::move(*block);
        it->second.digest = BundleDigest(it->second);
        auto& recent = history_[robot];
        std::erase_if(recent, [&](const Bundle& b) { return b.digest == it->second.digest; });
        recent.push_back(it->second);
        if (recent.size() > kHistory) recent.erase(recent.begin());
        // A re-sent bundle of an unchanged solution needs no new check.
        const auto last = bundles_.find(robot);
        const bool same = last != bundles_.end() && last->second.digest == it->second.digest;
        bundles_[robot] = std::move(it->second);
        pending_.erase(it);
        dirty_ = dirty_ || !same;
        if (waiting_) {
            const v1::CertificateRound round = *waiting_;  // OnRound may reset waiting_
            OnRound(round);
        }
        return true;
    });
}

void CertifierActor::Tick() {
    ResendIfStalled();
    if (!anchor_) return;
    const auto now = std::chrono::steady_clock::now();
    if (lanczos_ && !lanczos_->Done()) {
        if (round_heard_) stalled_since_.reset();  // a peer took part: not stalled
        const bool silent = now - round_progress_ >= config_.round_timeout ||
                            (stalled_since_ && now - *stalled_since_ >= config_.round_timeout);
        if (!silent) {
            // Stalled after the re-sends while the bundles changed: a robot may never have had
            // the named ones (one that just began reading a neighbour's stream): reopen on the
            // current bundles. The silence clock keeps running from the first stalled round.
            slam::PoseGraph graph;
            Eigen::MatrixXd X;
            if (dirty_ && now - round_progress_ >= 2 * config_.round_resend &&
                Assemble(&graph, &X)) {
                dirty_ = false;
                if (!stalled_since_) stalled_since_ = round_opened_;
                StartRound();
            }
            return;
        }
        // A robot's certifier stays silent (not running, or lost the round): this graph is
        // checked centrally instead; the next change of a bundle opens a distributed round again.
        lanczos_.reset();
        stalled_since_.reset();
        ++fallbacks_;
        slam::PoseGraph graph;
        Eigen::MatrixXd X;
        if (Assemble(&graph, &X)) CheckCentrally(graph, X, v1::CERTIFICATE_PATH_FALLBACK, bundles_);
        return;
    }
    slam::PoseGraph graph;
    Eigen::MatrixXd X;
    if (!dirty_ || !Assemble(&graph, &X)) return;
    dirty_ = false;
    if (SettledSinceCertified()) {
        ++skipped_;
        return;
    }
    if (config_.distributed) {
        stalled_since_.reset();
        StartRound();
    } else {
        CheckCentrally(graph, X, v1::CERTIFICATE_PATH_CENTRALISED, bundles_);
    }
}

void CertifierActor::CheckCentrally(const slam::PoseGraph& graph, const Eigen::MatrixXd& X,
                                    v1::CertificatePath path,
                                    const std::map<int, Bundle>& bundles) {
    const auto Q = slam::ConnectionLaplacian(graph);
    const auto result = certify::Certify(Q, X, 3, config_.certificate);
    ++checks_;
    Publish(result, static_cast<std::uint32_t>(X.rows()), graph.edges.size(), path, bundles);
    if (result.status == certify::CertificateResult::Status::kNotOptimal &&
        level_ < config_.max_staircase_steps) {
        Escape(Q, X, result.eigenvector, result.gradient_tolerance, bundles);
    }
}

void CertifierActor::Publish(const certify::CertificateResult& result, std::uint32_t rank,
                             std::uint64_t edges, v1::CertificatePath path,
                             const std::map<int, Bundle>& bundles) {
    {
        std::lock_guard lock(verdict_mutex_);
        certificate_ = result;
    }
    NoteVerdict(result.status == certify::CertificateResult::Status::kCertified, bundles);
    auto report = ToProto(result, rank);
    *report.mutable_header() = MakeHeader(RobotId(), NextSequence(), 0);
    report.set_iteration(edges);  // which graph: its edge count
    report.set_path(path);
    Send(*out_, transport::Pack(report), true);
}

void CertifierActor::Escape(const Eigen::SparseMatrix<double>& Q, const Eigen::MatrixXd& X,
                            const Eigen::VectorXd& v, double gradient_tolerance,
                            const std::map<int, Bundle>& bundles) {
    const auto escaped = certify::EscapeSaddle(Q, X, 3, v, gradient_tolerance);
    if (escaped.status != certify::EscapeResult::Status::kEscaped) return;
    ++level_;
    ++escapes_;
    int column = 0;
    for (const auto& [robot, b] : bundles) {
        certify::PoseBlocks blocks;
        blocks.ids = b.block.ids;
        blocks.blocks = escaped.X.middleCols(column, b.block.blocks.cols());
        blocks.staircase_level = level_;
        column += static_cast<int>(b.block.blocks.cols());
        auto proto = ToProto(blocks);
        *proto.mutable_header() = MakeHeader(RobotId(), NextSequence(), 0);
        Send(*out_, transport::Pack(proto), true);
    }
    bundles_.clear();  // wait for blocks at the new rank
}

// Distributed rounds: the anchor opens them; every certifier builds its rows of S from the
// named bundles and runs its share of Lanczos over CertificateVector/CertificateReduction.

void CertifierActor::SubscribeRounds() {
    for (int r : Wiring().robots) {
        if (r != RobotId()) OpenClient(Edge::kCertify, r);
    }
    On(v1::CertificateRound::descriptor()->full_name(), [this](const transport::Message& m) {
        const auto round = transport::Unpack<v1::CertificateRound>(m);
        if (!round || !IsValidRound(*round)) return false;
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
    const RoundShare share = ShareOf(RobotId(), chosen);
    round_edges_ = share.round_edges;
    certify::LocalCertificateProblem problem;
    if (!certify::MakeLocalProblem(RobotId(), own.block.ids, own.block.blocks, share.edges,
                                   share.far, &problem)) {
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
        v.set_block_size(kCertificateBlock);
        for (const auto& id : ids) *v.add_pose_ids() = ToProto(id);
        v.mutable_values()->Add(values.data(), values.data() + values.size());
        transport::Message m = transport::Pack(v);
        Send(*out_, m, true);
        RememberSent(&round_sent_, std::move(m));
    };
    const auto send_reduction = [this](int step, int stage, const std::vector<double>& values) {
        v1::CertificateReduction r;
        *r.mutable_header() = MakeHeader(RobotId(), NextSequence(), 0);
        r.set_round(round_);
        r.set_step(static_cast<std::uint32_t>(step));
        r.set_stage(static_cast<std::uint32_t>(stage));
        r.mutable_values()->Add(values.begin(), values.end());
        transport::Message m = transport::Pack(r);
        Send(*out_, m, true);
        RememberSent(&round_sent_, std::move(m));
    };
    lanczos_ = certify::MakeRoundParticipant(std::move(problem), Wiring().robots, round_,
                                             config_.lanczos, send_vector, send_reduction);
    round_began_ = std::chrono::steady_clock::now();
    lanczos_->Begin();
    auto early = std::move(early_[round_]);
    early_.clear();
    for (const auto& m : early) Deliver(m);
    RoundFinished();
}

void CertifierActor::Deliver(const transport::Message& m) {
    std::uint64_t round = 0;
    const auto vector_proto =
        m.Is<v1::CertificateVector>() ? transport::Unpack<v1::CertificateVector>(m) : std::nullopt;
    const auto reduction_proto = m.Is<v1::CertificateReduction>()
                                     ? transport::Unpack<v1::CertificateReduction>(m)
                                     : std::nullopt;
    const auto vector = vector_proto ? FromProto(*vector_proto) : std::nullopt;
    const auto reduction = reduction_proto ? FromProto(*reduction_proto) : std::nullopt;
    if (vector) round = vector->round;
    if (reduction) round = reduction->round;
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
        lanczos_->OnVector(vector->robot, vector->step, vector->ids, vector->values);
    } else {
        lanczos_->OnReduction(reduction->robot, reduction->step, reduction->stage,
                              reduction->values);
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
    certify::DistributedVerdict verdict = lanczos_->Verdict();
    {
        std::lock_guard lock(verdict_mutex_);
        if (verdict_ && verdict_->round == verdict.round) return;  // already counted
    }
    round_us_ += static_cast<std::uint64_t>(std::chrono::duration_cast<std::chrono::microseconds>(
                                                std::chrono::steady_clock::now() - round_began_)
                                                .count());
    // The anchor decides: the round's sums and lambda_min by the central rule, with the PSD test
    // of S + e D of the round's graph (the bundles the round named: one X, one edge set). The
    // graph, Q and X go before S + e D is factorized: the factor is the anchor's peak of memory.
    std::optional<certify::PsdTestFunction> psd_at;
    std::optional<certify::CertificateResult> central;
    if (anchor_) {
        slam::PoseGraph graph;
        Eigen::MatrixXd X;
        if (Assemble(round_bundles_, &graph, &X)) {
            const Eigen::SparseMatrix<double> Q = slam::ConnectionLaplacian(graph);
            if (config_.cross_check) {
                central = certify::Certify(Q, X, 3, config_.certificate);
                verdict.central_lambda_min = central->lambda_min;
            }
            psd_at = certify::RoundPsdTest(Q, X);
        }
    }
    std::optional<certify::CertificateResult> decided;
    if (psd_at) decided = certify::DecideRound(verdict, config_.certificate, *psd_at);
    psd_at.reset();
    {
        std::lock_guard lock(verdict_mutex_);
        verdict_ = verdict;
    }
    ++rounds_;
    ++checks_;
    lanczos_steps_ += static_cast<std::uint64_t>(verdict.steps);
    if (!anchor_) return;
    if (!decided) {  // the round's bundles no longer assemble: no verdict; the next round will
        dirty_ = true;
        return;
    }
    const bool fallback = decided->status == certify::CertificateResult::Status::kInconclusive &&
                          verdict.status == certify::DistributedVerdict::Status::kNotConverged &&
                          !dirty_;
    if (!fallback) {
        Publish(*decided, round_rank_, round_edges_, v1::CERTIFICATE_PATH_DISTRIBUTED,
                round_bundles_);
        if (decided->status != certify::CertificateResult::Status::kNotOptimal ||
            level_ >= config_.max_staircase_steps) {
            return;
        }
    }
    slam::PoseGraph graph;  // the same bundles assemble as above
    Eigen::MatrixXd X;
    if (!Assemble(round_bundles_, &graph, &X)) return;
    if (fallback) {
        // The eigen-solve ran out of steps at a settled iterate: no changed bundle will open
        // another round, so the anchor, which holds every bundle, checks this graph itself.
        ++fallbacks_;
        CheckCentrally(graph, X, v1::CERTIFICATE_PATH_FALLBACK, round_bundles_);
        return;
    }
    // The escape stays centralised: the anchor computes the eigenvector on the round's graph.
    const Eigen::SparseMatrix<double> Q = slam::ConnectionLaplacian(graph);
    if (!central) central = certify::Certify(Q, X, 3, config_.certificate);
    if (central->status == certify::CertificateResult::Status::kNotOptimal) {
        Escape(Q, X, central->eigenvector, central->gradient_tolerance, round_bundles_);
    }
}

}  // namespace certislam::actors
