// One robot's actor graph: ingest -> descriptor -> loop matcher -> RBCD solver -> certifier, and
// the TSDF mapper (keyframes + the solver's trajectory; submaps to and from peers) when the
// team's wiring has map addresses, in one ZeroMQ context, over the team's wiring.
#pragma once

#include <chrono>
#include <map>
#include <memory>
#include <string>

#include "actors/certifier_actor.h"
#include "actors/descriptor_actor.h"
#include "actors/ingest_actor.h"
#include "actors/loop_matcher_actor.h"
#include "actors/mapper_actor.h"
#include "actors/solver_actor.h"

namespace certislam::actors {

/// Settings of every actor of a robot.
struct RobotNodeConfig {
    IngestConfig ingest;                   ///< pacing
    slam::ScanContextConfig scan_context;  ///< descriptor
    LoopMatcherConfig matcher;             ///< loop closures
    /// RBCD of a growing graph (`solver.mode: rounds`): asynchronous while keyframes and loops
    /// arrive, then synchronous RBCD++ rounds once the graph is final, to the gradient the
    /// certificate needs (the back end `solve --distributed` measures); a restarted robot's peers
    /// rejoin it in a new round session. synchronous = false: asynchronous updates throughout.
    SolverActorConfig solver = [] {
        SolverActorConfig c;
        c.synchronous = true;
        c.async_until_final = true;
        c.rounds.rel_grad_tol = 1e-9;
        return c;
    }();
    CertifierConfig certifier;  ///< certificate
    MapperConfig mapper;        ///< TSDF submaps
    bool mapping = true;  ///< run the mapper (when the wiring has map addresses for every robot)
    std::chrono::milliseconds quiet{1500};  ///< done: certified and no change for this long

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// The six actors of one robot (the mapper only with mapping on and map addresses).
class RobotNode {
  public:
    /// `context` must outlive the node (shared by all robots of a process for inproc).
    RobotNode(zmq::context_t& context, const TeamWiring& wiring, KeyframeSource source,
              RobotNodeConfig config);
    ~RobotNode();

    /// Starts the actors (consumers first, ingest last).
    void Start();
    /// Asks every actor to stop after its current handler, without waiting (thread-safe).
    void RequestStop();
    /// Stops them (asks all first, so their current handlers end together, then joins each).
    void Stop();

    /// The solver's state now.
    SolverSnapshot Snapshot() const { return solver_->Snapshot(); }
    /// True when the keyframes ended, every matcher finished, the last certificate says
    /// certified for the graph as it is, and nothing changed for `quiet`.
    bool Done() const;
    /// Bytes this robot's actors sent on edges that reach other robots.
    std::uint64_t BytesSentToPeers() const;
    /// The same, per actor ("descriptor", "loop_matcher", "solver", "certifier", "mapper").
    std::map<std::string, std::uint64_t> BytesSentToPeersByActor() const;
    /// Loops this robot's matcher found.
    int LoopsFound() const { return matcher_->LoopsFound(); }
    /// Loops this robot's matcher withdrew (they dropped out of its consistent set).
    int LoopsWithdrawn() const { return matcher_->Withdrawn(); }
    /// The loop matcher (its counters: verified, rejected, clouds requested, skipped).
    const LoopMatcherActor& Matcher() const { return *matcher_; }
    /// The certifier (its counters: rounds, Lanczos steps, skipped re-checks).
    const CertifierActor& Certifier() const { return *certifier_; }
    /// The TSDF mapper; nullptr when the node runs none.
    MapperActor* Mapper() { return mapper_.get(); }
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
    std::unique_ptr<MapperActor> mapper_;
};

}  // namespace certislam::actors
