// Endpoint bookkeeping and typed dispatch shared by the robot actors.
#include "actors/node_actor.h"

namespace certislam::actors {

NodeActor::NodeActor(std::string name, zmq::context_t& context, TeamWiring wiring)
    : Actor(std::move(name), context), wiring_(std::move(wiring)) {
    wiring_.Validate();
}

transport::Endpoint& NodeActor::OpenServer(Edge edge, transport::Role role) {
    endpoints_.push_back(
        std::make_unique<transport::Endpoint>(Context(), ServerConfig(wiring_, edge, role)));
    auto& endpoint = *endpoints_.back();
    WatchEndpoint(endpoint, [this](transport::Message& m) { Dispatch(m); });
    return endpoint;
}

transport::Endpoint& NodeActor::OpenClient(Edge edge, int peer, transport::Role role) {
    endpoints_.push_back(
        std::make_unique<transport::Endpoint>(Context(), ClientConfig(wiring_, edge, peer, role)));
    auto& endpoint = *endpoints_.back();
    WatchEndpoint(endpoint, [this](transport::Message& m) { Dispatch(m); });
    return endpoint;
}

void NodeActor::On(const std::string& type_name, TypedHandler handler) {
    handlers_[type_name] = std::move(handler);
}

bool NodeActor::Send(transport::Endpoint& endpoint, const transport::Message& message,
                     bool to_peers) {
    return Sent(endpoint.Send(message), message, to_peers);
}

bool NodeActor::SendToRobot(transport::Endpoint& endpoint, int robot,
                            const transport::Message& message, bool to_peers) {
    return Sent(endpoint.SendToRobot(static_cast<std::uint32_t>(robot), message), message,
                to_peers);
}

bool NodeActor::Sent(transport::SendStatus status, const transport::Message& message,
                     bool to_peers) {
    if (status != transport::SendStatus::kSent) {
        CountQueueFull();
        return false;
    }
    if (to_peers) bytes_to_peers_.fetch_add(message.ByteSize(), std::memory_order_relaxed);
    return true;
}

void NodeActor::CloseEndpoints() { endpoints_.clear(); }

void NodeActor::Dispatch(transport::Message& message) {
    const auto it = handlers_.find(message.type_name());
    if (it == handlers_.end()) return;
    if (!it->second(message)) CountMalformed();
}

}  // namespace certislam::actors
