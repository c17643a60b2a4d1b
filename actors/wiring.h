// Where a robot's logical edges live: per robot and edge the address its publisher binds, and
// the CURVE keys that secure tcp edges; builds the endpoint configurations actors open.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "transport/curve.h"
#include "transport/endpoint_config.h"

namespace certislam::actors {

/// The logical edges of a robot node (each is one publisher's stream, or the cloud server).
/// kMap (the TSDF mapper's submaps) is optional: a team without its addresses runs no mapper.
enum class Edge { kKeyframes, kDescriptors, kLoops, kClouds, kPoses, kBundle, kCertify, kMap };

/// The edge's name in addresses and logs ("keyframes", ...).
const char* EdgeName(Edge edge);

/// Addresses and keys of a whole team, as one robot sees it.
struct TeamWiring {
    int robot = 0;            ///< this robot
    std::vector<int> robots;  ///< every robot of the team, ascending
    /// robots -> edge -> address its publisher (or cloud server) binds and peers connect to.
    std::map<int, std::map<Edge, std::string>> addresses;
    std::optional<transport::KeyPair> own_keys;  ///< set: tcp edges use CURVE
    std::map<int, std::string> public_keys;      ///< robot -> its CURVE public key (Z85)

    /// Throws std::invalid_argument unless robot is in robots, every robot has every edge, and
    /// with CURVE every robot has a valid public key.
    void Validate() const;
};

/// True when every robot of the team has an address for `edge`.
bool HasEdgeEverywhere(const TeamWiring& wiring, Edge edge);

/// Addresses of an all-in-one-process team: inproc://certislam/r<k>/<edge>.
TeamWiring InprocWiring(int robot, const std::vector<int>& robots);

/// Sockets an all-in-one-process team of `robots` may open, an upper bound: each robot's actors'
/// endpoints plus a subscription per peer and edge (so quadratic in the team); `front_end`: the
/// keyframe robots' ingest, descriptor, matcher and mapper too, not only solver and certifier.
int InprocTeamSockets(int robots, bool front_end);

/// Publisher (or router for kClouds) of `edge` on this robot: binds its address.
transport::EndpointConfig ServerConfig(const TeamWiring& wiring, Edge edge,
                                       transport::Role role = transport::Role::kPublisher);

/// Subscriber (or dealer for kClouds) connected to robot `peer`'s `edge`.
transport::EndpointConfig ClientConfig(const TeamWiring& wiring, Edge edge, int peer,
                                       transport::Role role = transport::Role::kSubscriber);

}  // namespace certislam::actors
