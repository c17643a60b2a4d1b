// The configuration of `certislam run` and `certislam robot` (JSON): the team, the keyframe
// source, the actors' settings and, for separate processes, addresses and CURVE keys.
#pragma once

#include <map>
#include <memory>
#include <string>
#include <vector>

#include "actors/robot_node.h"
#include "actors/wiring.h"
#include "slam/simulator.h"

namespace certislam::bin {

/// One robot's network identity (robot mode).
struct RobotEndpointConfig {
    std::string host = "127.0.0.1";  ///< address peers connect to ("*" binds all interfaces)
    int base_port = 0;               ///< edges on base_port .. base_port + 6
    std::string public_key;          ///< PREFIX.pub of `certislam keygen` (empty: no CURVE)
    std::string secret_key;          ///< PREFIX.key, read only by the robot itself
};

/// Everything the configuration file says.
struct TeamConfig {
    std::vector<int> robots;                     ///< team, ascending
    slam::SimulatorConfig simulator;             ///< source: the mission simulator
    int max_keyframes = 0;                       ///< keyframes per robot at most (0: all)
    actors::RobotNodeConfig node;                ///< actors' settings
    std::map<int, RobotEndpointConfig> network;  ///< robot mode: per robot
    std::string log_dir;  ///< durable per-robot logs here (replayed on start); empty: none
    std::string path;     ///< the file it came from (for messages)
};

/// The node settings of `robot` (its durable log paths under log_dir).
actors::RobotNodeConfig NodeConfigFor(const TeamConfig& config, int robot);

/// Reads a JSON configuration. Throws std::runtime_error naming the file and the field.
TeamConfig LoadTeamConfig(const std::string& path);

/// The wiring of `robot` over tcp (robot mode; CURVE when keys are configured).
actors::TeamWiring TcpWiring(const TeamConfig& config, int robot);

/// A shared simulated mission: each robot's keyframes generated on demand.
class SimulatedSource {
  public:
    explicit SimulatedSource(const TeamConfig& config);
    /// The source of one robot's keyframes (valid while this object lives).
    actors::KeyframeSource For(int robot) const;
    /// Keyframes robot `robot` will publish.
    int NumKeyframes(int robot) const;
    /// Ground truth of robot `robot` in robot 0's odometry frame (for evaluation).
    slam::Trajectory Truth(int robot) const;

  private:
    int max_keyframes_;
    std::shared_ptr<const slam::MissionGenerator> generator_;
};

/// Writes each robot's trajectory (TUM) and report.json into `dir`; returns the JSON report.
std::string WriteTeamOutputs(const std::string& dir, const std::vector<int>& robots,
                             const std::vector<actors::SolverSnapshot>& snapshots,
                             const std::vector<slam::Trajectory>& truth, std::uint64_t bytes_sent,
                             double seconds);

}  // namespace certislam::bin
