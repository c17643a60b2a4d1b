// Sensor ingest actor: pulls keyframes from a source (simulator, files) and publishes them on the
// robot's keyframe stream once its local consumers have subscribed; then an end-of-stream marker.
#pragma once

#include <atomic>
#include <chrono>
#include <deque>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "actors/durable_log.h"
#include "actors/node_actor.h"
#include "actors/streams.h"
#include "slam/core/keyframe.h"

namespace certislam::actors {

/// The next keyframe of this robot, or nullopt at the end of the data.
using KeyframeSource = std::function<std::optional<slam::Keyframe>()>;

/// Settings of the ingest actor.
struct IngestConfig {
    int local_subscribers = 3;                         ///< wait for this many subscribers, >= 0
    std::chrono::milliseconds period{2};               ///< one keyframe per period, > 0
    std::chrono::milliseconds end_marker_period{500};  ///< end marker repeated this often, > 0
    std::string log_path;      ///< durable keyframe log (replayed on start); empty: none
    std::string log_identity;  ///< the mission identity written in a new log's header

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// Publishes Keyframe messages (cloud as a zero-copy frame) at most one per period.
class IngestActor final : public NodeActor {
  public:
    IngestActor(zmq::context_t& context, TeamWiring wiring, KeyframeSource source,
                IngestConfig config);
    ~IngestActor() override { Stop(); }

    /// True once the source is exhausted and the end marker sent.
    bool Finished() const { return finished_.load(); }
    /// Keyframes published so far (replayed ones included).
    int Published() const { return published_.load(); }
    /// Keyframes replayed from the durable log at start.
    int Replayed() const { return replayed_.load(); }

  protected:
    void OnStart() override;
    void OnStop() override { CloseEndpoints(); }

  private:
    void Tick();
    void SendEnd();

    KeyframeSource source_;
    IngestConfig config_;
    transport::Endpoint* out_ = nullptr;
    std::atomic<bool> finished_{false};
    std::atomic<int> published_{0};
    std::atomic<int> replayed_{0};
    std::unique_ptr<DurableLog> log_;
    std::deque<transport::Message> replay_;  ///< logged keyframes still to publish
    int logged_ = 0;                         ///< keyframes the log held at start
};

}  // namespace certislam::actors
