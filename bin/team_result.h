// The JSON report of a pose-graph team run (cost, verdict, rounds, bytes between robots, peak
// RSS of this process): written by `solve --distributed` and by each robot process.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "actors/pose_graph_team.h"

namespace certislam::bin {

/// The report of a pose-graph team run (cost, verdict, team rounds, bytes between robots by
/// actor and robot, certificate rounds and Lanczos steps); `"path": "distributed"`.
nlohmann::json TeamResultJson(const actors::PoseGraphTeamResult& result, int robots,
                              const std::string& transport = "inproc");

}  // namespace certislam::bin
