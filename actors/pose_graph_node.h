// A back-end-only robot: its block of a pose-graph file (PoseGraphActor) feeds the real RBCD
// solver and certifier actors, in one ZeroMQ context, over the team's wiring. No LiDAR front end.
#pragma once

#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <string>

#include "actors/certifier_actor.h"
#include "actors/pose_graph_actor.h"
#include "actors/solver_actor.h"

namespace certislam::actors {

/// Settings of a pose-graph robot's actors.
struct PoseGraphNodeConfig {
    /// RBCD (solver.odometry_edges is set false); synchronous RBCD++ rounds by default: the
    /// whole graph is known once the source has sent it.
    SolverActorConfig solver = [] {
        SolverActorConfig c;
        c.synchronous = true;
        return c;
    }();
    CertifierConfig certifier;              ///< certificate
    std::chrono::milliseconds quiet{1500};  ///< done: certified and no change for this long

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// The three actors of one pose-graph robot: source, solver, certifier.
class PoseGraphNode {
  public:
    /// `context` must outlive the node (shared by all robots of a process for inproc).
    PoseGraphNode(zmq::context_t& context, const TeamWiring& wiring, slam::RobotGraph graph,
                  PoseGraphNodeConfig config);
    ~PoseGraphNode();

    /// Starts the actors (consumers first, the source last).
    void Start();
    /// Stops them (the source first).
    void Stop();

    /// The solver's state now.
    SolverSnapshot Snapshot() const { return solver_->Snapshot(); }
    /// True when the block went out, the solver heard every end marker, the last certificate
    /// says certified and nothing changed for `quiet`.
    bool Done() const;
    /// Bytes this robot's actors sent on edges that reach other robots, per actor ("pose_graph",
    /// "solver", "certifier").
    std::map<std::string, std::uint64_t> BytesSentToPeersByActor() const;
    /// The certifier (its counters: rounds, Lanczos steps, escapes).
    const CertifierActor& Certifier() const { return *certifier_; }
    /// The robot's id.
    int robot() const { return robot_; }

  private:
    int robot_;
    PoseGraphNodeConfig config_;
    std::unique_ptr<CertifierActor> certifier_;
    std::unique_ptr<SolverActor> solver_;
    std::unique_ptr<PoseGraphActor> source_;
};

}  // namespace certislam::actors
