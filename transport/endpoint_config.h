// Configuration of one socket endpoint of a logical edge, and the table that binds logical edge
// names to addresses (inproc://, ipc://, tcp://) so actor code never names a transport.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "transport/connection_guard.h"
#include "transport/curve.h"
#include "transport/message.h"
#include "transport/shm_segment.h"

namespace certislam::transport {

/// The socket pattern of an endpoint.
enum class Role {
    kPublisher,   ///< stream out (XPUB: sees subscriptions, which start the handshake)
    kSubscriber,  ///< stream in (SUB, subscribed to the broadcast and its robot's topics)
    kDealer,      ///< requests out / control client (DEALER)
    kRouter,      ///< requests in / control server (ROUTER, unroutable sends are errors)
    kPush,        ///< reliable one-way out (PUSH)
    kPull,        ///< reliable one-way in (PULL)
};

/// What happens when a queue is full.
enum class Delivery {
    kLatest,    ///< sensor streams: receiver keeps the newest, drops the oldest; sender drops
                ///< instead of blocking; every drop is counted
    kReliable,  ///< control/solver: never dropped; a full queue blocks the sender up to
                ///< send_timeout_ms, then Send returns kBackpressure (nothing is lost silently)
};

/// One endpoint of a logical edge.
struct EndpointConfig {
    std::string edge;  ///< logical edge name, e.g. "keyframes"
    Role role = Role::kPublisher;
    std::vector<std::string> bind;     ///< addresses to bind (tcp port 0 or * = ephemeral)
    std::vector<std::string> connect;  ///< addresses to connect to (one per peer)
    Delivery delivery = Delivery::kReliable;
    std::size_t max_queue_messages = 1000;     ///< per queue (ZeroMQ HWM and receive queue)
    std::size_t max_queue_bytes = 512u << 20;  ///< receive queue byte bound
    int send_timeout_ms = 1000;                ///< kReliable: longest a Send blocks (-1 = forever)
    int reconnect_interval_ms = 100;           ///< ZeroMQ reconnect interval to a lost peer
    /// Kernel send and receive buffer of the socket's connections (ZMQ_SNDBUF/ZMQ_RCVBUF),
    /// bytes; 0 keeps the OS default (Linux autotunes up to several MB; an explicit size is
    /// capped by net.core.rmem/wmem_max). 1 MiB: the bytes in flight stay in the L2 cache
    /// between the sender's and the receiver's kernel copies (faster than autotuning on loopback).
    int socket_buffer_bytes = 1 << 20;
    std::optional<CurveConfig> curve;  ///< CURVE security (tcp:// edges between robots)
    DecodeLimits limits;               ///< bounds on received frames
    /// Longest a new connection may take to finish the ZMTP (and CURVE) handshake before it is
    /// dropped (ZMQ_HANDSHAKE_IVL; libzmq's default is 30 s, which lets idle unauthenticated
    /// connections hold descriptors that long); 0 = no deadline.
    int handshake_timeout_ms = 2000;
    /// Pending-connection queue of a listening socket (ZMQ_BACKLOG; libzmq's default is 100, which
    /// a reconnecting flood keeps full, so the kernel drops a peer's SYN and TCP backs off for
    /// seconds); the kernel caps it at net.core.somaxconn. > 0.
    int listen_backlog = 4096;
    /// Caps on accepted connections of a socket bound to tcp:// (ConnectionGuard).
    ConnectionCaps connection_caps;
    /// This robot, stamped on control messages it sends; a subscriber's robot topic.
    std::uint32_t robot_id = 0;
    std::string node_name;  ///< this actor, stamped on control messages it sends
    /// An edge whose addresses are all ipc:// moves each binary frame of at least
    /// shm_threshold_bytes (but those of Endpoint::SendToRobot) through POSIX shared memory: only
    /// a descriptor goes on the socket and the receiver's frame points into its read-only
    /// mapping. Receivers accept descriptors
    /// only on such an edge (elsewhere they are dropped and counted). A descriptor not taken
    /// within shm.loan_ttl is void (so the reaper can reclaim a segment whose reader died): a
    /// receiver lagging further behind drops it, counted in dropped_shm; raise loan_ttl there.
    bool shm_enabled = true;
    std::size_t shm_threshold_bytes = std::size_t{64} << 10;  ///< smallest frame sent via shm
    std::size_t shm_pool_segments = 4;  ///< pre-faulted segments kept for copies of heap frames
    ShmConfig shm;                      ///< segment family, loan time-to-live, size bound

    /// Throws std::invalid_argument naming the field, value and rule (no address, an address
    /// that is not inproc://, ipc:// or tcp://, a zero bound, bad keys).
    void Validate() const;

    /// True when every address is ipc:// (so both ends share the host) and shm is enabled.
    bool UsesShm() const;
};

/// Logical edge name -> endpoint configurations, filled from the configuration file.
class EdgeTable {
  public:
    /// Adds (or replaces) an endpoint under key "edge/role", e.g. "keyframes/sub". Validates it.
    void Add(const std::string& key, EndpointConfig config);
    /// The configuration under key. Throws std::invalid_argument naming the unknown key.
    const EndpointConfig& Get(const std::string& key) const;
    /// True when key is configured.
    bool Has(const std::string& key) const { return table_.count(key) > 0; }
    /// Every configured key, sorted.
    std::vector<std::string> Keys() const;

  private:
    std::map<std::string, EndpointConfig> table_;
};

/// True when address starts with inproc://, ipc:// or tcp:// and has something after it.
bool IsSupportedAddress(const std::string& address);

}  // namespace certislam::transport
