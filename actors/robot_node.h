// One robot's actor graph: ingest -> descriptor -> loop matcher -> RBCD solver -> certifier
// (the TSDF mapper is not wired yet), in one ZeroMQ context, over the team's wiring.
#pragma once

#include <chrono>
#include <memory>

#include "actors/certifier_actor.h"
#include "actors/descriptor_actor.h"
#include "actors/ingest_actor.h"
#include "actors/loop_matcher_actor.h"
#include "actors/solver_actor.h"

namespace certislam::actors {

/// Settings of every actor of a robot.
struct RobotNodeConfig {
    IngestConfig ingest;                    ///< pacing
    slam::ScanContextConfig scan_context;   ///< descriptor
    LoopMatcherConfig matcher;              ///< loop closures
    SolverActorConfig solver;               ///< RBCD
    CertifierConfig certifier;              ///< certificate
    std::chrono::milliseconds quiet{1500};  ///< done: certified and no change for this long

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// The five actors of one robot.
class RobotNode {
  public:
    /// `context` must outlive the node (shared by all robots of a process for inproc).
    RobotNode(zmq::context_t& context, const TeamWiring& wiring, KeyframeSource source,
              RobotNodeConfig config);
    ~RobotNode();

    /// Starts the actors (consumers first, ingest last).
    void Start();
    /// Stops them (ingest first).
    void Stop();

    /// The solver's state now.
    SolverSnapshot Snapshot() const { return solver_->Snapshot(); }
    /// True when the keyframes ended, every matcher finished, the last certificate says
    /// certified for the graph as it is, and nothing changed for `quiet`.
    bool Done() const;
    /// Bytes this robot's actors sent on edges that reach other robots.
    std::uint64_t BytesSentToPeers() const;
    /// Loops this robot's matcher found.
    int LoopsFound() const { return matcher_->LoopsFound(); }
    /// The robot's id.
    int robot() const { return robot_; }

  private:
    int robot_;
    RobotNodeConfig config_;
    std::unique_ptr<CertifierActor> certifier_;
    std::unique_ptr<SolverActor> solver_;
    std::unique_ptr<LoopMatcherActor> matcher_;
    std::unique_ptr<DescriptorActor> descriptor_;
    std::unique_ptr<IngestActor> ingest_;
};

}  // namespace certislam::actors
