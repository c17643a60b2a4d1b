// Live keyframes from LIO-SAM's topics: clouds paired with odometry by stamp and selected as the
// bag source does (slam/io/rosbag, slam/core/keyframe_selection), handed to the ingest actor
// through a bounded queue that drops its oldest keyframe when full (and counts it).
#pragma once

#include <Eigen/Geometry>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "actors/ingest_actor.h"
#include "slam/core/keyframe.h"
#include "slam/core/keyframe_selection.h"
#include "slam/io/rosbag/rosbag_source_io.h"

namespace certislam::actors {

/// Pairing, selection and queueing of live keyframes.
struct LiveIngestConfig {
    double max_stamp_gap_s = 0.01;  ///< a cloud pairs with the nearest odometry within this, >= 0
    slam::RosbagCloudFrame cloud_frame = slam::RosbagCloudFrame::kAuto;  ///< as the bag source
    bool select_keyframes = true;             ///< LIO-SAM's distance / rotation rule on the pairs
    slam::KeyframeSelectionConfig selection;  ///< its thresholds
    int queue_capacity = 100;                 ///< keyframes waiting for the ingest actor, >= 1
    int odometry_buffer = 1000;               ///< recent odometry kept for pairing, >= 1
    double end_after_silence_s = 0.0;         ///< end the stream after this silence; 0: never

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// Counters of the live ingest.
struct LiveIngestStats {
    int clouds = 0;        ///< cloud messages received
    int odometry = 0;      ///< odometry messages received
    int unpaired = 0;      ///< clouds with no odometry within max_stamp_gap_s
    int out_of_order = 0;  ///< paired clouds older than the previous one (dropped)
    int selected = 0;      ///< pairs that became keyframes
    int dropped = 0;       ///< keyframes dropped from the full queue (oldest first)
    int handed_out = 0;    ///< keyframes the ingest actor took
    int queued = 0;        ///< keyframes waiting now
    bool ended = false;    ///< the stream ended (Close or silence)
    std::optional<std::int64_t> last_message_stamp_ns;  ///< header stamp of the last message
    double silent_s = 0.0;  ///< wall seconds since the last message (0 before the first)
};

/// Thread-safe: the ROS callbacks push, the ingest actor pops (blocking).
class LiveKeyframes {
  public:
    /// Validates `config` (throws std::invalid_argument).
    explicit LiveKeyframes(LiveIngestConfig config);

    /// An odometry message: T_odom_sensor at `stamp_ns`, header.frame_id `frame_id`.
    void OnOdometry(std::int64_t stamp_ns, const std::string& frame_id,
                    const Eigen::Isometry3d& T_odom_sensor);
    /// A decoded cloud message (points as published, in frame `frame_id`).
    void OnCloud(std::int64_t stamp_ns, const std::string& frame_id, slam::PointCloud cloud);
    /// No more messages: pending clouds are paired, and the source ends once the queue drains.
    void Close();

    /// The ingest actor's source: blocks until a keyframe is queued (indices consecutive from 0
    /// in hand-out order) or the stream ended (nullopt).
    KeyframeSource Source();
    /// Counters now.
    LiveIngestStats Stats() const;
    /// T_odom_sensor of every keyframe handed out, by index.
    std::vector<Eigen::Isometry3d> HandedOut() const;

  private:
    struct Odom {
        std::int64_t stamp_ns;
        std::string frame_id;
        Eigen::Isometry3d T_odom_sensor;
    };
    struct Cloud {
        std::int64_t stamp_ns;
        std::string frame_id;
        slam::PointCloud points;
    };
    std::optional<slam::Keyframe> Pop();
    void ResolveLocked(bool all);
    void PairLocked(Cloud cloud);
    void MarkArrivalLocked(std::int64_t stamp_ns);
    bool SilentLocked() const;

    LiveIngestConfig config_;
    slam::KeyframeSelector selector_;
    mutable std::mutex mutex_;
    std::condition_variable ready_;
    std::deque<Odom> odometry_;         ///< by stamp
    std::deque<Cloud> pending_;         ///< clouds whose pairing is not yet decided
    std::deque<slam::Keyframe> queue_;  ///< selected, waiting for the ingest actor
    std::vector<Eigen::Isometry3d> handed_out_;
    std::optional<std::int64_t> last_paired_ns_;
    std::optional<std::chrono::steady_clock::time_point> last_arrival_;
    bool closed_ = false;
    LiveIngestStats stats_;
};

}  // namespace certislam::actors
