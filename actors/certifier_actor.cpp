// Certifier: bundles in; centrally (joint Q and X at the anchor) or as a distributed round
// (certifier_actor_rounds.cpp); report out, escape blocks out.
#include "actors/certifier_actor.h"

#include <algorithm>
#include <stdexcept>

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
    if (lanczos.max_krylov < 2 || lanczos.check_every < 1 || !(lanczos.tolerance > 0.0)) {
        throw std::invalid_argument(
            "CertifierConfig.lanczos: max_krylov >= 2, check_every >= 1, tolerance > 0");
    }
}

namespace {

constexpr std::size_t kHistory = 16;  ///< distinct bundles kept per robot for rounds

/// FNV-1a over raw bytes.
void Mix(std::uint64_t* h, const void* data, std::size_t size) {
    const auto* bytes = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < size; ++i) *h = (*h ^ bytes[i]) * 1099511628211ull;
}

/// Mixes every edge's ends, measurement and weights (both digests hash the graph the same way).
template <typename Edges>
void MixEdges(std::uint64_t* h, const Edges& edges) {
    for (const auto& e : edges) {
        Mix(h, &e.a, sizeof(e.a));
        Mix(h, &e.b, sizeof(e.b));
        Mix(h, e.T_a_b.matrix().data(), sizeof(double) * 16);
        Mix(h, &e.kappa, sizeof(e.kappa));
        Mix(h, &e.tau, sizeof(e.tau));
    }
}

}  // namespace

std::uint64_t CertifierActor::Digest(const Bundle& b) {
    std::uint64_t h = 14695981039346656037ull;
    const int phase = b.status.phase();
    Mix(&h, &phase, sizeof(phase));
    for (const auto& id : b.block.ids) Mix(&h, &id, sizeof(id));
    const Eigen::Index dims[2] = {b.block.blocks.rows(), b.block.blocks.cols()};
    Mix(&h, dims, sizeof(dims));
    Mix(&h, b.block.blocks.data(),
        sizeof(double) * static_cast<std::size_t>(b.block.blocks.size()));
    MixEdges(&h, b.edges);
    return h;
}

std::uint64_t CertifierActor::GraphDigest(const Bundle& b) {
    std::uint64_t h = 14695981039346656037ull;
    for (const auto& id : b.block.ids) Mix(&h, &id, sizeof(id));
    const Eigen::Index rank = b.block.blocks.rows();
    Mix(&h, &rank, sizeof(rank));
    MixEdges(&h, b.edges);
    return h;
}

bool CertifierActor::SettledSinceCertified() const {
    // The certified round proved f* >= tr(Lambda) - eta d n for its graph; that bound holds for
    // any X on the same graph, and a block within a small relative move of the certified one
    // changes f by at most 2 ||X Q|| ||dX|| + ||Q|| ||dX||^2: no new round is worth its bytes.
    // A new edge, a withdrawn one, a new pose, a new rank (escape) or a larger move re-checks.
    if (certified_bundles_.empty() || certified_bundles_.size() != bundles_.size()) return false;
    for (const auto& [robot, b] : bundles_) {
        const auto it = certified_bundles_.find(robot);
        if (it == certified_bundles_.end()) return false;
        const Bundle& c = it->second;
        if (b.status.phase() != c.status.phase() || GraphDigest(b) != GraphDigest(c) ||
            b.block.blocks.rows() != c.block.blocks.rows() ||
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
        if (!status) return false;
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
        it->second.digest = Digest(it->second);
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
        if (Assemble(&graph, &X)) CheckCentrally(graph, X, v1::CERTIFICATE_PATH_FALLBACK);
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
        CheckCentrally(graph, X, v1::CERTIFICATE_PATH_CENTRALISED);
    }
}

bool CertifierActor::Assemble(const std::map<int, Bundle>& bundles, slam::PoseGraph* graph,
                              Eigen::MatrixXd* X) const {
    if (bundles.size() != Wiring().robots.size()) return false;
    // Every robot final, at one rank, its block covering its poses.
    std::map<int, int> offset;
    const int rank = static_cast<int>(bundles.begin()->second.block.blocks.rows());
    for (const auto& [robot, b] : bundles) {
        if (b.status.phase() != v1::SolverStatus::PHASE_CONVERGED) return false;
        if (b.block.blocks.rows() != rank || b.block.ids.size() != b.status.num_poses()) {
            return false;
        }
        offset[robot] = graph->n;
        for (const auto& id : b.block.ids) graph->ids.push_back(id);
        graph->n += static_cast<int>(b.block.ids.size());
    }
    X->resize(rank, 4 * graph->n);
    for (const auto& [robot, b] : bundles)
        X->middleCols(4 * offset[robot], b.block.blocks.cols()) = b.block.blocks;
    const auto index = [&](const slam::PoseId& id) -> int {
        const auto it = bundles.find(id.robot);
        if (it == bundles.end() || id.index >= int(it->second.block.ids.size())) return -1;
        return offset[id.robot] + id.index;
    };
    for (const auto& [robot, b] : bundles) {
        for (const auto& e : b.edges) {
            const int i = index(e.a), j = index(e.b);
            if (i < 0 || j < 0) return false;  // a newer bundle of the other robot is coming
            graph->edges.push_back(slam::MeasurementOf(e, i, j));
        }
    }
    return true;
}

void CertifierActor::CheckCentrally(const slam::PoseGraph& graph, const Eigen::MatrixXd& X,
                                    v1::CertificatePath path) {
    const auto Q = slam::ConnectionLaplacian(graph);
    const auto result = certify::Certify(Q, X, 3, config_.certificate);
    ++checks_;
    NoteVerdict(result.status == certify::CertificateResult::Status::kCertified, bundles_);
    auto report = ToProto(result, static_cast<std::uint32_t>(X.rows()));
    *report.mutable_header() = MakeHeader(RobotId(), NextSequence(), 0);
    report.set_iteration(graph.edges.size());  // which graph: its edge count
    report.set_path(path);
    Send(*out_, transport::Pack(report), true);
    if (result.status == certify::CertificateResult::Status::kNotOptimal &&
        level_ < config_.max_staircase_steps) {
        Escape(Q, X, result.eigenvector, result.gradient_tolerance, bundles_);
    }
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
        PoseBlocks blocks;
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

}  // namespace certislam::actors
