// Reads the transport part of a robot's configuration file (YAML): logical edges bound to
// inproc://, ipc:// or tcp:// addresses with their queue policy, and the CURVE key files
// (written by `certislam keygen`) of this robot and of the robots it allows.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>

#include "transport/curve.h"
#include "transport/endpoint_config.h"

namespace certislam::transport {

/// The transport settings of one robot, as read from its configuration file.
///
///     robot_id: 1
///     node_name: robot1
///     keys:
///       own: keys/robot1.key        # this robot's key pair (certislam keygen --out keys/robot1)
///       allow: {2: keys/robot2.pub} # robot id -> public key file: the ZAP allow-list
///     edges:
///       keyframes/pub: {role: publisher, bind: inproc://keyframes, delivery: latest,
///                       max_queue_messages: 10, max_queue_bytes: 104857600}
///       rbcd/dealer:   {role: dealer, connect: tcp://10.0.0.2:5601, curve: client,
///                       server_key: keys/robot2.pub}
///
/// Edge fields: role (publisher subscriber dealer router push pull), bind, connect (an address
/// or a list), delivery (latest reliable), max_queue_messages, max_queue_bytes, send_timeout_ms,
/// reconnect_interval_ms, curve (server client; needs keys.own), server_key (client: the
/// server's .pub file), shm (true false: large frames of an ipc:// edge via shared memory),
/// shm_threshold_bytes, shm_pool_segments, socket_buffer_bytes (see EndpointConfig). Key paths are
/// relative to the file's folder. Other top-level sections belong to other layers and are ignored;
/// an unknown field inside an edge is an error.
struct TransportFileConfig {
    std::uint32_t robot_id = 0;                       ///< stamped on control messages
    std::string node_name;                            ///< stamped on control messages
    std::optional<KeyPair> own_keys;                  ///< keys.own, when given
    std::map<std::string, std::uint32_t> allow_list;  ///< keys.allow: public key (Z85) -> robot
    EdgeTable edges;                                  ///< "edge/role" -> endpoint configuration
};

/// Parses YAML text. base_dir resolves relative key paths; source names the text in errors.
/// Throws std::runtime_error naming source:line and the field on any error.
TransportFileConfig ParseTransportConfig(const std::string& yaml_text, const std::string& base_dir,
                                         const std::string& source);

/// Reads and parses a configuration file. Throws std::runtime_error naming file:line.
TransportFileConfig LoadTransportConfig(const std::string& path);

}  // namespace certislam::transport
