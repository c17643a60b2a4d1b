// The demo's second path: the same simulated keyframes through the whole actor graph (six
// actors per robot, every robot in this process, talking over inproc), as `certislam run` does.
#pragma once

#include <cstdint>
#include <vector>

#include "slam/keyframe.h"
#include "slam/trajectory.h"

namespace certislam::bin {

/// What the actor graph produced.
struct ActorMissionResult {
    bool done = false;                         ///< every robot certified and quiet in time
    bool certified = false;                    ///< the last certificate heard says certified
    std::vector<slam::Trajectory> trajectory;  ///< [robot], in the anchor robot's frame
    std::vector<int> inter_robot_loops;        ///< [robot] inter-robot loops its solver knows
    std::uint64_t bytes_sent = 0;              ///< bytes on edges between robots, measured
    double seconds = 0.0;                      ///< start to done
};

/// Runs robots[k] (keyframes with clouds) through one RobotNode per robot over inproc until
/// every node is done or `timeout_s` passes. `rank` and `query_stride` as in the demo.
ActorMissionResult RunThroughActors(const std::vector<std::vector<slam::Keyframe>>& robots,
                                    double timeout_s);

}  // namespace certislam::bin
