// Certifier actor, bundle streams: which robots' solver bundles it reads, how a bundle is
// received, and the requests (BundleRequest) for bundles it needs and does not hold: solvers
// send a bundle only when it changed, so whatever a certifier missed it asks for.
#include <algorithm>
#include <chrono>
#include <set>

#include "actors/certifier_actor.h"

namespace certislam::actors {
namespace {

constexpr std::size_t kHistory = 16;  ///< distinct bundles kept per robot for rounds
constexpr int kMaxBackoffs = 4;       ///< re-asks for a bundle wait round_resend * 2^k, k <= this
/// Asks after a verdict wait round_resend * 2^k, k <= this (64 s at 500 ms): every solver answers
/// with its whole bundle, changed or not (86 MB of 342 MB on sphere2500 in 400 s at 2^4).
constexpr int kMaxRecheckBackoffs = 7;

}  // namespace

void CertifierActor::ReadBundlesOf(int robot) {
    const auto& team = Wiring().robots;
    if (std::find(team.begin(), team.end(), robot) == team.end()) return;  // not of the team
    if (bundle_streams_.insert(robot).second) OpenClient(Edge::kBundle, robot);
}

void CertifierActor::SubscribeBundles() {
    // The anchor reads every robot's bundles (it names them in rounds and checks centrally when
    // a round falls silent); in distributed mode the others read their own and, once they know
    // them, their neighbours' (from their own edges, or a round naming them). A bundle sent
    // before a stream was read is asked for (RequestBundles): solvers send each bundle once.
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
        const int robot = int(status->header().robot_id());
        if (status->phase() != v1::SolverStatus::PHASE_CONVERGED) {  // neighbours announced
            if (robot == RobotId() && !anchor_) {
                for (const auto n : status->neighbor_robots()) ReadBundlesOf(int(n));
            }
            return true;
        }
        pending_[robot] = Bundle{*status, {}, {}, 0};
        pending_since_[robot] = std::chrono::steady_clock::now();
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
        pending_since_.erase(robot);
        dirty_ = dirty_ || !same;
        OnBundleClosed(robot);
        return true;
    });
}

void CertifierActor::OnBundleClosed(int robot) {
    if (robot == RobotId() && !anchor_ && config_.distributed) {
        // Neighbours known from the own edges: their streams are read before a round needs them.
        for (const auto& e : bundles_.at(robot).edges) {
            for (const slam::PoseId& id : {e.a, e.b}) ReadBundlesOf(id.robot);
        }
    }
    if (waiting_) {
        const v1::CertificateRound round = *waiting_;  // OnRound may reset waiting_
        OnRound(round);
    }
}

void CertifierActor::SendRequest(const std::set<int>& robots) {
    if (robots.empty()) return;
    v1::BundleRequest request;
    *request.mutable_header() = MakeHeader(RobotId(), NextSequence(), 0);
    for (int r : robots) request.add_robot_ids(static_cast<std::uint32_t>(r));
    Send(*out_, transport::Pack(request), true);
}

void CertifierActor::RequestBundles(const std::set<int>& robots) {
    const auto now = std::chrono::steady_clock::now();
    std::set<int> ask;
    for (int r : robots) {
        // Arriving now; a bundle begun longer ago lost its end (its solver restarted mid-bundle).
        if (pending_.count(r) && now - pending_since_[r] < config_.round_resend) continue;
        Request& last = requested_[r];
        // A large bundle takes long to arrive on a loaded host: each re-ask re-sends it to every
        // subscriber, so the asks back off (also across answers that were not what was wanted).
        const auto wait = config_.round_resend * (1 << std::min(last.count, kMaxBackoffs));
        if (last.count > 0 && now - last.at < wait) continue;
        last.at = now;
        ++last.count;
        ask.insert(r);
    }
    SendRequest(ask);
}

// Asks for every bundle it needs and does not hold, with backoff, so no certifier waits forever
// for a bundle sent before it read the stream, lost in a restart or on the way: a waiting
// round's named bundles; the anchor every robot's it has none of (it started late, restarted, or
// an escape emptied bundles_), another certifier its own and its known neighbours'. The anchor
// also asks for every robot's current bundle once per stalled round and, backing off, after a
// verdict that was not certified (RequestAfterVerdict).
void CertifierActor::RequestWhatIsMissing() {
    std::set<int> wanted = waiting_ ? missing_ : std::set<int>{};
    const std::set<int> team(Wiring().robots.begin(), Wiring().robots.end());
    for (int r : anchor_ ? team : bundle_streams_) {
        if (!bundles_.count(r)) wanted.insert(r);
    }
    std::erase_if(requested_, [&](const auto& entry) { return !wanted.count(entry.first); });
    RequestBundles(wanted);
    if (!anchor_) return;
    const auto now = std::chrono::steady_clock::now();
    const bool in_round = lanczos_ && !lanczos_->Done();
    if (in_round && !stall_requested_ && now - round_progress_ >= 2 * config_.round_resend) {
        stall_requested_ = true;
        SendRequest(team);
    }
    if (!in_round) RequestAfterVerdict(team, now);
}

// After a verdict neither certified nor followed by an escape a new round needs new bundles; a
// solver sends one when its bundle changes, and this ask covers a change that did not reach the
// anchor (lost, or never flagged): a changed answer opens the round (dirty_), an unchanged one
// does not. The first ask waits round_resend, each later one twice as long, up to
// 2^kMaxRecheckBackoffs.
void CertifierActor::RequestAfterVerdict(const std::set<int>& team,
                                         std::chrono::steady_clock::time_point now) {
    if (!recheck_) return;
    const auto wait = config_.round_resend * (1 << std::min(recheck_->count, kMaxRecheckBackoffs));
    if (now - recheck_->at < wait) return;
    recheck_->at = now;
    ++recheck_->count;
    SendRequest(team);
}

}  // namespace certislam::actors
