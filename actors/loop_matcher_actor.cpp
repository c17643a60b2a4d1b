// Loop matcher: brute-force Scan Context over the (strided) pairs this robot owns, gated cloud
// requests to lower robots (replies downsampled at the registration voxel), GICP verification on
// worker threads (verdicts applied in candidate order), PCM, loop closures (and withdrawals) out.
#include "actors/loop_matcher_actor.h"

#include <pthread.h>
#include <algorithm>

#include <boost/asio/post.hpp>
#include <cmath>
#include <stdexcept>
#include <string>

#include "actors/convert.h"
#include "actors/convert_descriptor.h"
#include "actors/streams.h"
#include "certislam/v1/control.pb.h"
#include "slam/core/check.h"
#include "slam/frontend/downsample.h"

namespace certislam::actors {
namespace {

void Require(bool ok, const std::string& field, double value, const std::string& rule) {
    if (!ok) {
        throw std::invalid_argument("LoopMatcherConfig." + field + " = " + std::to_string(value) +
                                    ": " + rule);
    }
}

slam::CloudRequestGateConfig GateConfig(const LoopMatcherConfig& config) {
    slam::CloudRequestGateConfig gate;
    gate.max_sc_distance = config.max_sc_distance;
    gate.place_window = config.place_window;
    return gate;
}

}  // namespace

void LoopMatcherConfig::Validate() const {
    Require(max_sc_distance > 0 && max_sc_distance <= 1, "max_sc_distance", max_sc_distance,
            "must be in (0, 1]");
    Require(query_stride >= 1, "query_stride", query_stride, "must be >= 1");
    Require(min_intra_gap >= 1, "min_intra_gap", min_intra_gap, "must be >= 1");
    Require(request_retry.count() > 0, "request_retry", request_retry.count(), "must be > 0");
    Require(max_rmse_m > 0, "max_rmse_m", max_rmse_m, "must be > 0");
    Require(place_window >= 0, "place_window", place_window, "must be >= 0");
    Require(prepared_clouds >= 0, "prepared_clouds", prepared_clouds, "must be >= 0");
    Require(registration_threads >= 1, "registration_threads", registration_threads,
            "must be >= 1");
    Require(max_candidates_per_query >= 0, "max_candidates_per_query", max_candidates_per_query,
            "must be >= 0");
    pcm.Validate();
    registration.Validate();
}

LoopMatcherActor::LoopMatcherActor(zmq::context_t& context, TeamWiring wiring,
                                   LoopMatcherConfig config)
    : NodeActor("loop_matcher", context, std::move(wiring)),
      config_(config),
      gate_((config.Validate(), GateConfig(config))),
      pcm_(config.pcm) {}

// Verdicts not applied yet are lost with the workers (a stopped matcher is not started again).
void LoopMatcherActor::OnStop() {
    if (workers_) {
        workers_->stop();  // registrations not started are dropped; running ones finish
        workers_->join();
        workers_.reset();
    }
    registrations_.clear();
    CloseEndpoints();
}

void LoopMatcherActor::OnStart() {
    // Each run of the actor has its own workers (a stopped pool cannot be started again).
    workers_ = std::make_unique<boost::asio::thread_pool>(config_.registration_threads);
    loops_out_ = &OpenServer(Edge::kLoops);
    clouds_server_ = &OpenServer(Edge::kClouds, transport::Role::kRouter);
    OpenClient(Edge::kKeyframes, RobotId());
    for (int r : Wiring().robots) {
        if (r > RobotId()) continue;  // pairs with higher robots are theirs to check
        OpenClient(Edge::kDescriptors, r);
        if (r < RobotId()) {
            cloud_clients_[r] = &OpenClient(Edge::kClouds, r, transport::Role::kDealer);
        }
    }
    On(v1::Keyframe::descriptor()->full_name(), [this](const transport::Message& m) {
        const auto keyframe = DecodeKeyframe(m);
        if (!keyframe || keyframe->robot != RobotId()) return false;
        OnOwnKeyframe(*keyframe);
        return true;
    });
    On(v1::ScanContextDescriptor::descriptor()->full_name(),
       [this](const transport::Message& m) { return OnDescriptor(m); });
    On(v1::CloudRequest::descriptor()->full_name(),
       [this](const transport::Message& m) { return OnCloudRequest(m); });
    On(v1::CloudReply::descriptor()->full_name(),
       [this](const transport::Message& m) { return OnCloudReply(m); });
    On(v1::Shutdown::descriptor()->full_name(), [this](const transport::Message& m) {
        const auto end = transport::Unpack<v1::Shutdown>(m);
        if (!end) return false;
        if (end->reason() == kEndOfDescriptors) {
            end_counts_[int(end->header().robot_id())] = end->count();
        }
        return true;
    });
    Every(std::chrono::milliseconds(100), [this] { Tick(); });
}

void LoopMatcherActor::OnOwnKeyframe(const slam::Keyframe& keyframe) {
    // Every own keyframe's cloud is kept for the life of the mission (any later query may match
    // it): at the registration voxel, the finest any registration or reply uses, not the scan's
    // full resolution.
    own_clouds_[keyframe.index] = config_.downsample_replies
                                      ? std::make_shared<slam::PointCloud>(slam::VoxelDownsample(
                                            *keyframe.cloud, config_.registration.voxel_m))
                                      : keyframe.cloud;
    if (own_odometry_.count(keyframe.index)) return;
    slam::KeyframeOdometry odometry{keyframe.T_odom_sensor, 0.0};
    if (const auto before = own_odometry_.find(keyframe.index - 1); before != own_odometry_.end()) {
        odometry.travelled_m =
            before->second.travelled_m +
            (keyframe.T_odom_sensor.translation() - before->second.T_odom.translation()).norm();
    }
    own_odometry_[keyframe.index] = odometry;
    pcm_.SetOdometry({RobotId(), keyframe.index}, odometry);
}

bool LoopMatcherActor::OnDescriptor(const transport::Message& m) {
    const auto proto = transport::Unpack<v1::ScanContextDescriptor>(m);
    if (!proto) return false;
    const auto id = FromProto(proto->pose_id());
    if (!id || id->robot > RobotId() || id->robot != int(proto->header().robot_id())) return false;
    // Counted for the end marker even when its body is bad: a re-send would bring the same bytes.
    received_[id->robot].insert(id->index);
    const auto sc = FromProto(*proto);
    if (!sc) return false;
    if (id->index % config_.query_stride != 0 || descriptors_.count(*id)) return true;
    slam::ScanContextColumns columns(*sc);
    std::vector<slam::LoopCandidate> candidates;
    for (const auto& [other, other_sc] : descriptors_) {
        // Own keyframe vs anything stored; a lower robot's keyframe vs own ones only.
        const bool own_new = id->robot == RobotId(), own_other = other.robot == RobotId();
        if (!own_new && !own_other) continue;
        if (own_new && own_other &&
            (!config_.intra_robot || id->index - other.index < config_.min_intra_gap)) {
            continue;
        }
        const slam::PoseId query = own_new ? *id : other;
        const slam::PoseId match = own_new ? other : *id;
        const auto& q = own_new ? columns : other_sc;
        const auto& c = own_new ? other_sc : columns;
        const auto best = slam::ScanContextDistance(q, c);
        if (best.distance < config_.max_sc_distance) {
            candidates.push_back({query, match, best.distance, best.yaw_rad});
        }
    }
    descriptors_.emplace(*id, std::move(columns));
    // Best first, so a capped query keeps its most similar places (ties: the older keyframe).
    std::stable_sort(candidates.begin(), candidates.end(),
                     [](const auto& a, const auto& b) { return a.sc_distance < b.sc_distance; });
    for (const auto& c : candidates) {
        int& count = considered_[{c.query.index, c.match.robot}];
        if (config_.max_candidates_per_query > 0 && count >= config_.max_candidates_per_query) {
            ++capped_;
            continue;
        }
        ++count;
        Consider(c);
    }
    return true;
}

void LoopMatcherActor::Consider(const slam::LoopCandidate& c) {
    if (!own_clouds_.count(c.query.index) ||
        (c.match.robot == RobotId() && !own_clouds_.count(c.match.index))) {
        deferred_.push_back({c, {}});
        return;
    }
    if (c.match.robot == RobotId()) {
        Verify(c, own_clouds_.at(c.match.index));
        return;
    }
    // A failed registration reopens its place: a windowed gate needs every verdict first.
    if (config_.place_window > 0) ApplyRegistrations(0);
    switch (gate_.Admit(c)) {
        case slam::CloudRequestGate::Decision::kSkip:
            ++skipped_;
            return;
        case slam::CloudRequestGate::Decision::kRegister:
            if (const auto it = peer_clouds_.find(c.match); it != peer_clouds_.end()) {
                Verify(c, it->second);
            } else {
                waiting_[c.match].push_back(c);  // its cloud is on the way
            }
            return;
        case slam::CloudRequestGate::Decision::kFetch:
            break;
    }
    waiting_[c.match].push_back(c);
    const std::uint64_t id = ++next_request_;
    pending_[id] = {c, std::chrono::steady_clock::now()};
    ++clouds_requested_;
    RequestCloud(id, pending_[id]);
}

void LoopMatcherActor::RequestCloud(std::uint64_t id, const Pending& p) {
    v1::CloudRequest request;
    *request.mutable_header() = MakeHeader(RobotId(), NextSequence(), 0);
    *request.mutable_pose_id() = ToProto(p.candidate.match);
    request.set_request_id(id);
    Send(*cloud_clients_.at(p.candidate.match.robot), transport::Pack(request), true);
}

slam::PointCloudPtr LoopMatcherActor::ReplyCloud(int index) {
    // Kept at the registration voxel (OnOwnKeyframe), where the requester registers anyway.
    const auto own = own_clouds_.find(index);
    return own == own_clouds_.end() ? nullptr : own->second;
}

bool LoopMatcherActor::OnCloudRequest(const transport::Message& m) {
    const auto request = transport::Unpack<v1::CloudRequest>(m);
    if (!request) return false;
    const auto id = FromProto(request->pose_id());
    if (!id) return false;
    v1::CloudReply reply;
    *reply.mutable_header() = MakeHeader(RobotId(), NextSequence(), 0);
    *reply.mutable_pose_id() = request->pose_id();
    reply.set_request_id(request->request_id());
    const slam::PointCloudPtr cloud = id->robot == RobotId() ? ReplyCloud(id->index) : nullptr;
    if (const auto it = own_odometry_.find(id->index);
        id->robot == RobotId() && it != own_odometry_.end()) {
        *reply.mutable_t_odom_base() = ToProto(it->second.T_odom);  // for the requester's PCM
        reply.set_travelled_m(it->second.travelled_m);
    }
    const auto message = EncodeCloudReply(reply, cloud);
    if (clouds_server_->SendTo(m.peer, message) == transport::SendStatus::kSent) {
        CountPeerBytes(message.ByteSize());
    }
    return true;
}

bool LoopMatcherActor::OnCloudReply(const transport::Message& m) {
    v1::CloudReply reply;
    const auto cloud = DecodeCloudReply(m, &reply);
    if (!cloud) return transport::Unpack<v1::CloudReply>(m).has_value();  // not found: retried
    const auto it = pending_.find(reply.request_id());
    if (it == pending_.end()) return true;  // a duplicate reply to a retried request
    const slam::PoseId match = it->second.candidate.match;
    pending_.erase(it);
    const auto T_odom = reply.has_t_odom_base() ? FromProto(reply.t_odom_base()) : std::nullopt;
    if (T_odom && std::isfinite(reply.travelled_m())) {
        pcm_.SetOdometry(match, {*T_odom, reply.travelled_m()});
    }
    const slam::PointCloudPtr kept = peer_clouds_[match] = *cloud;
    const auto waiting = std::move(waiting_[match]);
    waiting_.erase(match);
    for (const auto& c : waiting) {
        if (StopRequested()) break;  // a full queue waits for a registration: stop sooner
        Verify(c, kept);
    }
    return true;
}

void LoopMatcherActor::Verify(const slam::LoopCandidate& c,
                              const slam::PointCloudPtr& match_cloud) {
    auto source = Prepared(c.query, own_clouds_.at(c.query.index), /*as_target=*/false);
    auto target = Prepared(c.match, match_cloud, /*as_target=*/true);
    // Prepared clouds are only read while registering (const trees and covariances).
    auto task = std::make_shared<std::packaged_task<slam::RegistrationResult()>>(
        [source = std::move(source), target = std::move(target), yaw = c.yaw_rad,
         config = config_.registration] {
            thread_local const bool named =  // once per worker, for `top -H` and perf
                pthread_setname_np(pthread_self(), "registration") == 0;
            (void)named;
            return slam::RegisterScans(source->Get(), target->Get(), slam::YawGuess(yaw), config);
        });
    // Two queued per thread keep the workers busy; more would hold prepared clouds for nothing.
    ApplyRegistrations(2 * static_cast<std::size_t>(config_.registration_threads) - 1);
    registrations_.push_back({c, task->get_future()});
    boost::asio::post(*workers_, [task] { (*task)(); });
}

void LoopMatcherActor::ApplyRegistrations(std::size_t at_most) {
    while (!registrations_.empty()) {
        auto& front = registrations_.front();
        if (registrations_.size() <= at_most &&
            front.result.wait_for(std::chrono::seconds(0)) != std::future_status::ready) {
            return;
        }
        Registration done = std::move(front);
        registrations_.pop_front();  // first: a registration that threw is dropped, not retried
        Apply(done.candidate, done.result.get());
    }
}

void LoopMatcherActor::Apply(const slam::LoopCandidate& c, const slam::RegistrationResult& result) {
    const slam::PoseId query = c.query, match = c.match;
    if (!result.accepted() || result.inlier_rmse_m > config_.max_rmse_m) {
        ++rejected_;
        if (match.robot != RobotId()) gate_.Failed(c);  // the place is open again
        return;
    }
    ++verified_;
    slam::LoopClosure loop;
    loop.a = match;  // the lower robot's (or older own) keyframe is the tail
    loop.b = query;
    loop.T_a_b = result.T_target_source;
    loop.kappa = result.kappa;
    loop.tau = result.tau;
    loop.fitness = result.inlier_rmse_m * result.inlier_rmse_m;
    if (!config_.reject_outliers) {
        sent_[{loop.a, loop.b}] = loop;
        SendLoop(ToProto(loop), loop.inter_robot());
        return;
    }
    // A peer that sent no odometry with its cloud cannot be checked: the loop is not used.
    if (pcm_.Add(loop, result.information)) pcm_dirty_ = true;
}

const slam::PreparedCloud& LoopMatcherActor::LazyPrepared::Get() {
    std::call_once(once_, [this] {
        prepared_ = std::make_unique<const slam::PreparedCloud>(*cloud_, config_, as_target_);
        cloud_.reset();
    });
    return *prepared_;
}

std::shared_ptr<LoopMatcherActor::LazyPrepared> LoopMatcherActor::Prepared(
    const slam::PoseId& id, const slam::PointCloudPtr& cloud, bool as_target) {
    const auto order = std::find(prepared_order_.begin(), prepared_order_.end(), id);
    if (order != prepared_order_.end()) {
        prepared_order_.erase(order);
        const auto kept = prepared_.find(id);
        CERTISLAM_CHECK(kept != prepared_.end());
        if (!as_target || kept->second->as_target()) {  // used again: now the latest
            prepared_order_.push_back(id);
            return kept->second;
        }
        prepared_.erase(kept);  // a source only: prepared again below, as a target
    }
    auto prepared = std::make_shared<LazyPrepared>(cloud, config_.registration, as_target);
    if (config_.prepared_clouds == 0) return prepared;
    if (static_cast<int>(prepared_order_.size()) >= config_.prepared_clouds) {
        prepared_.erase(prepared_order_.front());
        prepared_order_.pop_front();
    }
    prepared_.emplace(id, prepared);
    prepared_order_.push_back(id);
    return prepared;
}

void LoopMatcherActor::SendLoop(v1::LoopClosure proto, bool inter_robot) {
    // The verdict version: increasing across restarts (wall clock), so the newest verdict wins.
    const auto now = std::chrono::system_clock::now().time_since_epoch();
    last_version_ = std::max<std::int64_t>(
        last_version_ + 1, std::chrono::duration_cast<std::chrono::nanoseconds>(now).count());
    *proto.mutable_header() = MakeHeader(RobotId(), NextSequence(), last_version_);
    Send(*loops_out_, transport::Pack(proto), inter_robot);
    loops_ = static_cast<int>(sent_.size());
}

void LoopMatcherActor::Reconcile() {
    pcm_dirty_ = false;
    std::map<std::pair<slam::PoseId, slam::PoseId>, slam::LoopClosure> consistent;
    for (const auto& loop : pcm_.Consistent()) consistent[{loop.a, loop.b}] = loop;
    for (auto it = sent_.begin(); it != sent_.end();) {
        if (consistent.count(it->first)) {
            ++it;
            continue;
        }
        const slam::LoopClosure gone = it->second;
        it = sent_.erase(it);
        ++withdrawn_;
        SendLoop(LoopWithdrawal(gone.a, gone.b), gone.inter_robot());
    }
    for (const auto& [ends, loop] : consistent) {
        if (!sent_.emplace(ends, loop).second) continue;
        SendLoop(ToProto(loop), loop.inter_robot());
    }
}

bool LoopMatcherActor::StreamEnded(int r) const {
    const auto end = end_counts_.find(r);
    if (end == end_counts_.end()) return false;
    const auto got = received_.find(r);
    return (got == received_.end() ? 0 : got->second.size()) >= end->second;
}

void LoopMatcherActor::Tick() {
    auto deferred = std::move(deferred_);
    deferred_.clear();
    for (const auto& p : deferred) Consider(p.candidate);
    const auto now = std::chrono::steady_clock::now();
    for (auto& [id, p] : pending_) {
        if (now - p.sent < config_.request_retry) continue;
        p.sent = now;
        RequestCloud(id, p);  // the peer was silent or not there yet
    }
    ApplyRegistrations(registrations_.size());
    if (pcm_dirty_) Reconcile();  // once per tick: a burst of verified loops, one clique search
    bool done = pending_.empty() && deferred_.empty() && registrations_.empty();
    for (int r : Wiring().robots) done = done && (r > RobotId() || StreamEnded(r));
    // A subscriber that (re)joined after we sent (a restarted robot's solver) gets every loop
    // accepted now again; solvers ignore verdicts they already hold.
    const std::size_t subscribers = loops_out_->subscribers();
    if (subscribers > seen_subscribers_) {
        for (const auto& [ends, loop] : sent_) SendLoop(ToProto(loop), loop.inter_robot());
    }
    seen_subscribers_ = subscribers;
    if (!done) return;
    ended_ = true;
    v1::Shutdown end;
    *end.mutable_header() = MakeHeader(RobotId(), NextSequence(), 0);
    end.set_reason(kEndOfLoops);
    std::uint64_t inter = 0;
    for (const auto& [ends, loop] : sent_) inter += loop.inter_robot() ? 1 : 0;
    end.set_count(inter);  // a solver holding fewer inter-robot loops of ours waits for them
    Send(*loops_out_, transport::Pack(end), true);
}

}  // namespace certislam::actors
