// Listens to every robot's loop stream (as the solver does) and keeps the accepted inter-robot
// loop closures that touch this robot, for drawing them.
#pragma once

#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <utility>
#include <vector>

#include "actors/node_actor.h"
#include "slam/core/loop_closure.h"

namespace certislam::actors {

/// Keeps the newest verdict per loop (a matcher's version in header.stamp_ns; withdrawals drop).
class LoopWatcherActor final : public NodeActor {
  public:
    LoopWatcherActor(zmq::context_t& context, TeamWiring wiring);
    ~LoopWatcherActor() override { Stop(); }

    /// Accepted inter-robot loops with one end on this robot now (thread-safe).
    std::vector<slam::LoopClosure> Loops() const;

  protected:
    void OnStart() override;
    void OnStop() override { CloseEndpoints(); }

  private:
    bool OnLoop(const transport::Message& m);

    struct Verdict {
        std::int64_t version = 0;
        std::optional<slam::LoopClosure> loop;  ///< empty: withdrawn
    };
    mutable std::mutex mutex_;
    std::map<std::pair<slam::PoseId, slam::PoseId>, Verdict> loops_;
};

}  // namespace certislam::actors
