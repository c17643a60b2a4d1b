// Pose-graph source actor: stands in for a robot's LiDAR front end (ingest, descriptor, loop
// matcher) when the robot's data is its block of a pose-graph file. Own poses go out as pose-only
// keyframes and the intra-robot edges as loop closures on the robot's keyframe stream (local);
// the inter-robot edges whose tail is own go out on its loop stream (every robot's solver reads
// it); then both end markers, repeated, and everything again to a subscriber that joins late.
#pragma once

#include <atomic>
#include <cstddef>
#include <vector>

#include "actors/node_actor.h"
#include "slam/core/graph_split.h"

namespace certislam::actors {

/// Publishes one robot's block of a pose graph.
class PoseGraphActor final : public NodeActor {
  public:
    /// `graph.robot` must be the wiring's robot.
    PoseGraphActor(zmq::context_t& context, TeamWiring wiring, slam::RobotGraph graph);
    ~PoseGraphActor() override { Stop(); }

    /// True once the block went out on both streams.
    bool Finished() const { return finished_.load(); }

  protected:
    void OnStart() override;
    void OnStop() override { CloseEndpoints(); }

  private:
    void SendBlock();
    void SendInterRobotEdges();
    void SendEnds();

    slam::RobotGraph graph_;
    transport::Endpoint* keyframes_out_ = nullptr;
    transport::Endpoint* loops_out_ = nullptr;
    std::size_t keyframe_subscribers_ = 0;  ///< subscribers when the block last went out
    std::size_t loop_subscribers_ = 0;      ///< subscribers when the edges last went out
    std::size_t inter_ends_ = 0;            ///< distinct ends of the inter-robot edges
    bool block_sent_ = false;
    bool edges_sent_ = false;
    std::atomic<bool> finished_{false};
};

}  // namespace certislam::actors
