// The configuration of `certislam run` and `certislam robot` (YAML or JSON): the team, the keyframe
// source, the actors' settings and, for separate processes, addresses and CURVE keys.
#pragma once

#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "actors/durable_log.h"
#include "actors/pose_graph_node.h"
#include "actors/pose_graph_team.h"
#include "actors/robot_node.h"
#include "actors/wiring.h"
#include "bin/config/team_config_sources.h"

namespace certislam::bin {

/// One robot's network identity (robot mode).
struct RobotEndpointConfig {
    std::string host = "127.0.0.1";  ///< address peers connect to ("*" binds all interfaces)
    int base_port = 0;               ///< edges on base_port + 1 .. base_port + 7 (map last)
    std::string public_key;          ///< PREFIX.pub of `certislam keygen` (empty: no CURVE)
    std::string secret_key;          ///< PREFIX.key, read only by the robot itself
    /// Set: the robot's edges are Unix sockets DIR/r<K>.<edge> (robots of one host), not tcp
    std::string ipc_dir;
};

/// Everything the configuration file says.
struct TeamConfig {
    std::vector<int> robots;                     ///< team, ascending
    SourceConfig source;                         ///< where the keyframes come from
    actors::RobotNodeConfig node;                ///< actors' settings
    std::map<int, RobotEndpointConfig> network;  ///< robot mode: per robot
    std::string log_dir;  ///< durable per-robot logs here (replayed on start); empty: none
    actors::StaleLogPolicy log_stale = actors::StaleLogPolicy::kRefuse;  ///< another mission's log
    double quiet_s = 1.5;  ///< a robot is done once certified and unchanged this long
    std::string path;      ///< the file it came from (for messages)
};

/// The node settings of `robot`: its durable log paths under log_dir, checked against the
/// mission's identity (a stale or corrupt log is refused or moved aside by log_stale; throws
/// std::runtime_error naming the log).
actors::RobotNodeConfig NodeConfigFor(const TeamConfig& config, int robot);

/// A pose-graph robot's settings from the node's: the whole graph is known, so RBCD++ rounds run
/// from the start, to solve --distributed's tolerance (not the keyframe robots' asynchronous mode).
actors::PoseGraphNodeConfig PoseGraphNodeConfigFrom(const actors::RobotNodeConfig& node);

/// Reads a configuration file (YAML; JSON is YAML too) against TeamConfigKeys() and checks the
/// team, the source and the network; for a pose-graph source also the settings its robots use
/// (PoseGraphNodeConfigFrom's). Throws std::runtime_error naming the file, the line and the key
/// path. Links no front end: what a back-end-only robot reads its configuration with.
TeamConfig ReadTeamConfig(const std::string& path);

/// For a keyframe source, checks every actor's settings and the simulator's (a pose-graph source:
/// nothing more than ReadTeamConfig did). Throws std::runtime_error naming the file and field.
void CheckActorSettings(const TeamConfig& config);

/// ReadTeamConfig, then CheckActorSettings (team_config_keyframes.cpp).
TeamConfig LoadTeamConfig(const std::string& path);

/// The wiring of `robot` as a process of its own (robot mode): tcp (CURVE when keys are
/// configured), or Unix sockets for robots with network.<robot>.ipc_dir.
actors::TeamWiring NetworkWiring(const TeamConfig& config, int robot);

/// Writes each robot's trajectory (TUM) and the report (`report_name`; none when empty) into
/// `dir` (nothing when empty); returns the JSON report. Per robot, where `source` has a reference:
/// ATE RMSE after aligning the robot alone (`ate_rmse_own_alignment`), in the team frame without
/// alignment
/// (`ate_rmse_team_frame`), and the error of its recovered odometry frame (`offset_error_m`,
/// `offset_error_deg`, worst over its keyframes). From `team` (actors::SummariseNodes of the
/// robots' nodes): the bytes between robots and the keys `solve --distributed` reports beside.
std::string WriteTeamOutputs(const std::string& dir, const std::vector<int>& robots,
                             const std::vector<actors::SolverSnapshot>& snapshots,
                             const TeamSource& source, const actors::PoseGraphTeamResult& team,
                             double seconds, const std::string& report_name,
                             const std::vector<nlohmann::json>& meshes = {});

/// Meshes the node's mapper (its own submaps and, where it fuses them, its peers') and writes
/// OUT_DIR/robot<ID>.mesh.ply (nothing when OUT_DIR is empty); returns the report's `mesh`
/// entry (null without a mapper). Throws std::runtime_error naming the file on failure.
nlohmann::json WriteRobotMesh(actors::RobotNode& node, const actors::RobotNodeConfig& config,
                              int id, const std::string& out_dir);

/// The human summary of a report of WriteTeamOutputs (verdict, per robot errors).
std::string TeamReportText(const std::string& report_json);

}  // namespace certislam::bin
