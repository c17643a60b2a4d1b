// One front end per demo run: the baselines of Table I on the team graph the actor graph
// solved, and the certified row and certificate from the actors themselves.
#pragma once

#include "bin/demo/demo_actors.h"
#include "bin/demo/demo_mission.h"
#include "certify/pipeline/mission.h"

namespace certislam::bin {

/// The actors' accepted loops (odometry edges left out), in discovery order: by the stamp of
/// the later keyframe of each loop (when the loop could first be found), then the earlier one.
std::vector<slam::LoopClosure> LoopsInDiscoveryOrder(
    const std::vector<std::vector<slam::Keyframe>>& robots,
    const std::vector<slam::LoopClosure>& edges);

/// The baselines (odometry, one-time alignment, local search from odometry and from the
/// alignment, each certified) on the team graph of `run.edges`; no certified RBCD (the actors
/// give it). Throws std::runtime_error when a robot met nobody.
certify::MissionResult BaselinesOnActorGraph(const std::vector<std::vector<slam::Keyframe>>& robots,
                                             const ActorMissionResult& run,
                                             const certify::MissionConfig& config,
                                             const certify::MissionProgress& progress = {});

/// The certified row, the certificate, the loops and the bytes from the actor graph into
/// `report`; its trajectories and poses into `mission` (certified, solution.poses and cost on
/// mission->graph, so the g2o file and every row share the graph).
void FillFromActors(const ActorMissionResult& run, certify::MissionResult* mission,
                    DemoReport* report);

}  // namespace certislam::bin
