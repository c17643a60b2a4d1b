// Common glue of the six robot actors: endpoints opened on the actor's thread from the team
// wiring, dispatch by message type, malformed payloads dropped and counted, bytes sent counted.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "actors/actor.h"
#include "actors/wiring.h"
#include "transport/endpoint.h"

namespace certislam::actors {

/// An actor of one robot node.
class NodeActor : public Actor {
  public:
    /// `wiring` says where every edge of the team lives.
    NodeActor(std::string name, zmq::context_t& context, TeamWiring wiring);

    /// Bytes of messages this actor sent to other robots' actors (envelope + frames).
    std::uint64_t BytesSentToPeers() const { return bytes_to_peers_.load(); }

  protected:
    /// Handles one message of a given payload type; returns false when its payload is malformed.
    using TypedHandler = std::function<bool(const transport::Message& message)>;

    /// Opens this robot's server endpoint of `edge` (actor thread only).
    transport::Endpoint& OpenServer(Edge edge, transport::Role role = transport::Role::kPublisher);
    /// Opens a client endpoint to robot `peer`'s `edge`; messages go to the handlers of On().
    transport::Endpoint& OpenClient(Edge edge, int peer,
                                    transport::Role role = transport::Role::kSubscriber);
    /// Registers the handler of payload type `type_name` (messages of other types: ignored).
    void On(const std::string& type_name, TypedHandler handler);
    /// Sends; counts bytes when the endpoint's edge crosses to other robots (`to_peers`).
    bool Send(transport::Endpoint& endpoint, const transport::Message& message, bool to_peers);
    /// Sends on a publisher to robot `robot`'s subscribers only; counts bytes as Send does.
    bool SendToRobot(transport::Endpoint& endpoint, int robot, const transport::Message& message,
                     bool to_peers);
    /// Adds bytes sent to other robots by other means than Send().
    void CountPeerBytes(std::uint64_t bytes) { bytes_to_peers_.fetch_add(bytes); }
    /// Closes every endpoint (call from OnStop()).
    void CloseEndpoints();

    const TeamWiring& Wiring() const { return wiring_; }
    int RobotId() const { return wiring_.robot; }
    /// Next sequence number of this actor's messages.
    std::uint64_t NextSequence() { return ++sequence_; }

  private:
    void Dispatch(transport::Message& message);
    bool Sent(transport::SendStatus status, const transport::Message& message, bool to_peers);

    TeamWiring wiring_;
    std::vector<std::unique_ptr<transport::Endpoint>> endpoints_;
    std::map<std::string, TypedHandler> handlers_;
    std::atomic<std::uint64_t> bytes_to_peers_{0};
    std::uint64_t sequence_ = 0;
};

}  // namespace certislam::actors
