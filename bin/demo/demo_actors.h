// The demo's main path: the simulated keyframes through the whole actor graph (one RobotNode per
// robot, every robot in this process, talking over inproc), as `certislam run` does.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "slam/core/keyframe.h"
#include "slam/core/loop_closure.h"
#include "slam/core/trajectory.h"
#include "slam/mapping/mesh.h"

namespace certislam::bin {

/// What the actor graph produced.
struct ActorMissionResult {
    bool done = false;                          ///< every robot certified and quiet in time
    bool certified = false;                     ///< the last certificate heard says certified
    std::string verdict = "none";               ///< that certificate's verdict, in words
    std::string certificate_path = "none";      ///< which check gave it: distributed round,
                                                ///< centralised, fallback (centralised after a
                                                ///< silent round)
    double lambda_min = 0.0;                    ///< lambda_min(S) of that certificate
    bool has_bound = false;                     ///< its bound below was proven
    double suboptimality_bound = 0.0;           ///< its f - f* bound (0 unless has_bound)
    double lower_bound = 0.0;                   ///< its f* lower bound (0 unless has_bound)
    double relative_suboptimality_bound = 0.0;  ///< its relative bound (0 unless has_bound)
    double cost = 0.0;                          ///< its objective f
    int rank = 0;                               ///< its relaxation rank
    std::vector<slam::Trajectory> trajectory;   ///< [robot], in the anchor robot's frame
    std::vector<int> anchor;                    ///< [robot] robot whose frame it is in
    std::vector<int> inter_robot_loops;         ///< [robot] inter-robot loops its solver knows
    int team_inter_robot_loops = 0;             ///< distinct inter-robot loops in the team graph
    std::vector<int> loops_found;               ///< [robot] loops its matcher accepts at the end
    std::vector<int> registrations;             ///< [robot] candidates its matcher registered
    std::vector<int> loops_verified;            ///< [robot] of those, registration accepted
    std::vector<std::uint64_t> solver_steps;    ///< [robot] block updates its solver made
    std::uint64_t bytes_sent = 0;               ///< bytes on edges between robots, measured
    slam::TriangleMesh mesh;  ///< robot 0's mapper: every robot's submaps fused, team frame
    int submaps = 0;          ///< submaps in robot 0's map (own + received)
    std::uint64_t map_bytes_sent = 0;  ///< compressed submap bytes the mappers sent to peers
    int certificate_rounds = 0;        ///< distributed rounds robot 0's certifier finished
    int saddle_escapes = 0;            ///< saddle escapes robot 0's certifier made
    std::uint64_t lanczos_steps = 0;   ///< their Lanczos steps (S v exchanges), all rounds
    int settled_skips = 0;  ///< changed bundles robot 0 did not re-check (settled, certified)
    std::map<std::string, std::uint64_t> bytes_by_actor;  ///< bytes_sent per actor, all robots
    /// The team graph the solvers hold at the end: every robot's own edges (odometry and
    /// accepted loops, with their weights), as SolverSnapshot::edges gives them.
    std::vector<slam::LoopClosure> edges;
    double seconds = 0.0;       ///< start to done
    double mesh_seconds = 0.0;  ///< robot 0's mapper fusing every submap into the mesh
    double stop_seconds = 0.0;  ///< stopping the robots' actors
};

/// Progress of the run: stage and fraction done in [0, 1].
using ActorProgress = std::function<void(const std::string& stage, double fraction)>;

/// Work on the final team graph (only `edges` is filled) on its own thread, from when every
/// robot's graph is final: beside the rounds, the certificate and robot 0's mesh fusion.
using WhileMeshing = std::function<void(const ActorMissionResult& graph)>;

/// The cloud of keyframe `index` of `robot`, made when the robot's ingest asks for it.
using CloudMaker = std::function<slam::PointCloudPtr(int robot, int index)>;

/// Runs robots[k] through one RobotNode per robot over inproc until every node is done or
/// `timeout_s` passes; every `query_stride`-th keyframe queries the loop matcher. A keyframe
/// without a cloud gets `make_cloud`'s on the robot's own ingest thread, so the robots' scans are
/// made in parallel and while the team works. The TSDF mappers run with voxels of `voxel_m` (0: no
/// mapper). `while_meshing` (if set) runs once every robot's graph is final (again on the edges
/// at the end should they differ), and has returned when this does.
ActorMissionResult RunThroughActors(const std::vector<std::vector<slam::Keyframe>>& robots,
                                    double timeout_s, double voxel_m, int query_stride,
                                    bool distributed_certificate = true,
                                    const ActorProgress& progress = {},
                                    const CloudMaker& make_cloud = {},
                                    const WhileMeshing& while_meshing = {});

}  // namespace certislam::bin
