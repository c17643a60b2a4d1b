// Live pairing of LIO-SAM clouds with odometry, keyframe selection and the bounded queue.
#include "actors/ros/live_keyframes.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace certislam::actors {

void LiveIngestConfig::Validate() const {
    const auto fail = [](const std::string& field, double value, const char* rule) {
        throw std::invalid_argument("LiveIngestConfig." + field + " = " + std::to_string(value) +
                                    ": " + rule);
    };
    if (!(max_stamp_gap_s >= 0.0) || !std::isfinite(max_stamp_gap_s)) {
        fail("max_stamp_gap_s", max_stamp_gap_s, "must be finite, >= 0");
    }
    if (queue_capacity < 1) fail("queue_capacity", queue_capacity, "must be >= 1");
    if (odometry_buffer < 1) fail("odometry_buffer", odometry_buffer, "must be >= 1");
    if (!(end_after_silence_s >= 0.0) || !std::isfinite(end_after_silence_s)) {
        fail("end_after_silence_s", end_after_silence_s, "must be finite, >= 0");
    }
    selection.Validate();
}

LiveKeyframes::LiveKeyframes(LiveIngestConfig config)
    : config_(config), selector_(config_.selection) {
    config_.Validate();
}

void LiveKeyframes::MarkArrivalLocked(std::int64_t stamp_ns) {
    stats_.last_message_stamp_ns = stamp_ns;
    last_arrival_ = std::chrono::steady_clock::now();
}

void LiveKeyframes::OnOdometry(std::int64_t stamp_ns, const std::string& frame_id,
                               const Eigen::Isometry3d& T_odom_sensor) {
    {
        std::lock_guard lock(mutex_);
        if (closed_) return;
        MarkArrivalLocked(stamp_ns);
        ++stats_.odometry;
        // Kept sorted by stamp (odometry normally arrives in order: a cheap insert at the end).
        auto it = std::upper_bound(odometry_.begin(), odometry_.end(), stamp_ns,
                                   [](std::int64_t s, const Odom& o) { return s < o.stamp_ns; });
        odometry_.insert(it, Odom{stamp_ns, frame_id, T_odom_sensor});
        while (static_cast<int>(odometry_.size()) > config_.odometry_buffer) odometry_.pop_front();
        ResolveLocked(false);
    }
    ready_.notify_all();
}

void LiveKeyframes::OnCloud(std::int64_t stamp_ns, const std::string& frame_id,
                            slam::PointCloud cloud) {
    {
        std::lock_guard lock(mutex_);
        if (closed_) return;
        MarkArrivalLocked(stamp_ns);
        ++stats_.clouds;
        pending_.push_back(Cloud{stamp_ns, frame_id, std::move(cloud)});
        // A cloud waits for an odometry at or after its stamp; a bounded wait (the queue size).
        while (static_cast<int>(pending_.size()) > config_.queue_capacity) {
            PairLocked(std::move(pending_.front()));
            pending_.pop_front();
        }
        ResolveLocked(false);
    }
    ready_.notify_all();
}

void LiveKeyframes::Close() {
    {
        std::lock_guard lock(mutex_);
        ResolveLocked(true);
        closed_ = true;
    }
    ready_.notify_all();
}

// A pending cloud's nearest odometry is known once an odometry at or after its stamp arrived
// (later ones are farther); with `all`, every pending cloud is paired with what there is.
void LiveKeyframes::ResolveLocked(bool all) {
    while (!pending_.empty()) {
        const bool decided =
            all || (!odometry_.empty() && odometry_.back().stamp_ns >= pending_.front().stamp_ns);
        if (!decided) return;
        PairLocked(std::move(pending_.front()));
        pending_.pop_front();
    }
}

// The bag source's rule: the odometry of nearest stamp within max_stamp_gap_s (ties: the earlier),
// the cloud mapped into the sensor frame when it is in the odometry's frame; then selection.
void LiveKeyframes::PairLocked(Cloud cloud) {
    const auto max_gap_ns = static_cast<std::int64_t>(std::llround(config_.max_stamp_gap_s * 1e9));
    auto it = std::lower_bound(odometry_.begin(), odometry_.end(), cloud.stamp_ns,
                               [](const Odom& o, std::int64_t s) { return o.stamp_ns < s; });
    const Odom* best = nullptr;
    std::int64_t best_gap = max_gap_ns;
    for (const auto& c : {it, it == odometry_.begin() ? odometry_.end() : it - 1}) {
        if (c == odometry_.end()) continue;
        const std::int64_t gap = std::llabs(c->stamp_ns - cloud.stamp_ns);
        if (gap <= best_gap) {
            best_gap = gap;
            best = &*c;
        }
    }
    if (best == nullptr) {
        ++stats_.unpaired;
        return;
    }
    if (last_paired_ns_ && cloud.stamp_ns < *last_paired_ns_) {
        ++stats_.out_of_order;
        return;
    }
    last_paired_ns_ = cloud.stamp_ns;
    if (config_.select_keyframes && !selector_.Accept(best->T_odom_sensor)) return;
    if (slam::CloudIsInOdomFrame(config_.cloud_frame, cloud.frame_id, best->frame_id)) {
        const Eigen::Isometry3f T_sensor_odom = best->T_odom_sensor.inverse().cast<float>();
        for (Eigen::Vector3f& x : cloud.points) x = T_sensor_odom * x;
    }
    slam::Keyframe kf;
    kf.stamp_ns = cloud.stamp_ns;
    kf.T_odom_sensor = best->T_odom_sensor;
    kf.cloud = std::make_shared<const slam::PointCloud>(std::move(cloud.points));
    ++stats_.selected;
    if (static_cast<int>(queue_.size()) >= config_.queue_capacity) {
        queue_.pop_front();
        ++stats_.dropped;
    }
    queue_.push_back(std::move(kf));
}

bool LiveKeyframes::SilentLocked() const {
    if (config_.end_after_silence_s <= 0.0 || !last_arrival_ || stats_.handed_out == 0) {
        return false;
    }
    const std::chrono::duration<double> silent = std::chrono::steady_clock::now() - *last_arrival_;
    return silent.count() > config_.end_after_silence_s;
}

std::optional<slam::Keyframe> LiveKeyframes::Pop() {
    std::unique_lock lock(mutex_);
    while (queue_.empty()) {
        if (!closed_ && SilentLocked()) {
            ResolveLocked(true);
            closed_ = true;
            continue;
        }
        if (closed_) {
            stats_.ended = true;
            return std::nullopt;
        }
        ready_.wait_for(lock, std::chrono::milliseconds(100));
    }
    slam::Keyframe kf = std::move(queue_.front());
    queue_.pop_front();
    kf.index = stats_.handed_out++;
    handed_out_.push_back(kf.T_odom_sensor);
    return kf;
}

KeyframeSource LiveKeyframes::Source() {
    return [this] { return Pop(); };
}

LiveIngestStats LiveKeyframes::Stats() const {
    std::lock_guard lock(mutex_);
    LiveIngestStats s = stats_;
    s.queued = static_cast<int>(queue_.size());
    if (last_arrival_) {
        s.silent_s =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - *last_arrival_)
                .count();
    }
    return s;
}

std::vector<Eigen::Isometry3d> LiveKeyframes::HandedOut() const {
    std::lock_guard lock(mutex_);
    return handed_out_;
}

}  // namespace certislam::actors
