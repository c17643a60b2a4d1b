// One robot of a team configuration as a process of its own: the options, configuration and
// errors of `certislam robot` and of the lean `certislam-robot` (bin/robot_main.cpp), and the
// pose-graph robot they both run. Links no front end: keyframe robots come in as a callback.
#pragma once

#include <CLI/CLI.hpp>
#include <functional>
#include <string>
#include <zmq.hpp>

#include "actors/wiring.h"
#include "bin/config/team_config.h"

namespace certislam::bin {

/// The command line of a robot process.
struct RobotCommandOptions {
    std::string config_path;   ///< team configuration (YAML or JSON)
    int id = -1;               ///< this robot's id
    std::string out_dir;       ///< robot<K>.report.json here (keyframe robots: and robot<K>.tum)
    double timeout_s = 300.0;  ///< give up after this many seconds
    std::string log_dir;       ///< durable log folder (overrides the configuration's log_dir)
    bool json = false;         ///< print the report as JSON
    double progress_s = 2.0;   ///< keyframe robots: progress line period (0: off)
    double snapshot_s = 5.0;   ///< keyframe robots: snapshot period of the outputs (0: off)
};

/// Adds the robot command's arguments and options to `app`.
void AddRobotCommandOptions(CLI::App& app, RobotCommandOptions* options);

/// A keyframe robot's run on its configuration and wiring (the context's ZAP handler is up);
/// returns the exit code.
using KeyframeRobotFn =
    std::function<int(zmq::context_t&, const actors::TeamWiring&, const TeamConfig&)>;

/// Reads the configuration (ReadTeamConfig), applies --log-dir, wires robot `options.id` (tcp or
/// ipc, CURVE with keys) and runs it: a pose-graph source here (source, solver and certifier
/// actors; prints its report), another source through `keyframes` (empty: refused, naming
/// source.kind). An error is printed as "PROGRAM: message" and gives kExitBadInput.
int RunRobotCommand(const RobotCommandOptions& options, const std::string& program,
                    const KeyframeRobotFn& keyframes);

}  // namespace certislam::bin
