// Endpoint configurations from a team's addresses and keys.
#include "actors/wiring.h"

#include <algorithm>
#include <stdexcept>

namespace certislam::actors {
namespace {

constexpr Edge kAllEdges[] = {Edge::kKeyframes, Edge::kDescriptors, Edge::kLoops,  Edge::kClouds,
                              Edge::kPoses,     Edge::kBundle,      Edge::kCertify};

bool IsTcp(const std::string& address) { return address.rfind("tcp://", 0) == 0; }

transport::EndpointConfig Base(const TeamWiring& wiring, Edge edge, transport::Role role) {
    transport::EndpointConfig config;
    config.edge = EdgeName(edge);
    config.role = role;
    config.delivery = transport::Delivery::kReliable;
    config.max_queue_messages = 100000;
    config.send_timeout_ms = 2000;
    config.robot_id = static_cast<std::uint32_t>(wiring.robot);
    config.node_name = "robot" + std::to_string(wiring.robot) + "/" + EdgeName(edge);
    return config;
}

}  // namespace

const char* EdgeName(Edge edge) {
    switch (edge) {
        case Edge::kKeyframes:
            return "keyframes";
        case Edge::kDescriptors:
            return "descriptors";
        case Edge::kLoops:
            return "loops";
        case Edge::kClouds:
            return "clouds";
        case Edge::kPoses:
            return "poses";
        case Edge::kBundle:
            return "bundle";
        case Edge::kCertify:
            return "certify";
        case Edge::kMap:
            return "map";
    }
    return "unknown";
}

void TeamWiring::Validate() const {
    if (std::find(robots.begin(), robots.end(), robot) == robots.end()) {
        throw std::invalid_argument("TeamWiring.robot = " + std::to_string(robot) +
                                    ": must be one of the team's robots");
    }
    for (int r : robots) {
        const auto it = addresses.find(r);
        for (Edge e : kAllEdges) {
            if (it == addresses.end() || !it->second.count(e) || it->second.at(e).empty()) {
                throw std::invalid_argument("TeamWiring.addresses[" + std::to_string(r) + "]." +
                                            EdgeName(e) + ": missing");
            }
        }
        if (own_keys && !transport::IsValidZ85Key(public_keys.count(r) ? public_keys.at(r) : "")) {
            throw std::invalid_argument("TeamWiring.public_keys[" + std::to_string(r) +
                                        "]: missing or not a 40-character Z85 key");
        }
    }
}

bool HasEdgeEverywhere(const TeamWiring& wiring, Edge edge) {
    return std::all_of(wiring.robots.begin(), wiring.robots.end(), [&](int r) {
        const auto it = wiring.addresses.find(r);
        return it != wiring.addresses.end() && it->second.count(edge) &&
               !it->second.at(edge).empty();
    });
}

TeamWiring InprocWiring(int robot, const std::vector<int>& robots) {
    TeamWiring wiring;
    wiring.robot = robot;
    wiring.robots = robots;
    for (int r : robots) {
        for (Edge e : kAllEdges) {
            wiring.addresses[r][e] = "inproc://certislam/r" + std::to_string(r) + "/" + EdgeName(e);
        }
        wiring.addresses[r][Edge::kMap] = "inproc://certislam/r" + std::to_string(r) + "/map";
    }
    return wiring;
}

transport::EndpointConfig ServerConfig(const TeamWiring& wiring, Edge edge, transport::Role role) {
    auto config = Base(wiring, edge, role);
    const std::string& address = wiring.addresses.at(wiring.robot).at(edge);
    config.bind = {address};
    if (wiring.own_keys && IsTcp(address)) {
        transport::CurveConfig curve;
        curve.server = true;
        curve.own = *wiring.own_keys;
        config.curve = curve;
    }
    return config;
}

transport::EndpointConfig ClientConfig(const TeamWiring& wiring, Edge edge, int peer,
                                       transport::Role role) {
    auto config = Base(wiring, edge, role);
    std::string address = wiring.addresses.at(peer).at(edge);
    // A server bound on all interfaces is reached on loopback by the robots of its host.
    if (const auto star = address.find("://*:"); star != std::string::npos) {
        address.replace(star, 5, "://127.0.0.1:");
    }
    config.connect = {address};
    if (wiring.own_keys && IsTcp(address)) {
        transport::CurveConfig curve;
        curve.server = false;
        curve.own = *wiring.own_keys;
        curve.server_public_z85 = wiring.public_keys.at(peer);
        config.curve = curve;
    }
    return config;
}

int InprocTeamSockets(int robots, bool front_end) {
    const int per_peer = front_end ? 8 : 4, own = front_end ? 64 : 32;
    return per_peer * robots * robots + own * robots + 64;
}

}  // namespace certislam::actors
