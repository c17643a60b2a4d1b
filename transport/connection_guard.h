// Connection caps on a listening socket: a per-peer-address and a total cap on its accepted
// TCP connections, enforced from the socket's monitor events (libzmq has no such option).
#pragma once

#include <atomic>
#include <cstddef>
#include <map>
#include <string>
#include <thread>
#include <zmq.hpp>

namespace certislam::transport {

/// Caps on the TCP connections one listening socket accepts (0 = no cap).
struct ConnectionCaps {
    std::size_t max_total = 1024;   ///< connections open at once on the socket
    std::size_t max_per_peer = 64;  ///< connections open at once from one remote address
};

/// Watches a socket's ZMQ_EVENT_ACCEPTED / DISCONNECTED / CLOSED events on its own thread and
/// shuts down (shutdown(2), so libzmq sees end of stream and closes it itself) every accepted
/// connection beyond the caps. Unauthenticated clients holding connections open are then dropped
/// at once instead of filling the process's descriptors; the handshake deadline (ZMQ_HANDSHAKE_IVL)
/// ends the ones under the caps.
class ConnectionGuard {
  public:
    /// Starts monitoring `socket` (which must outlive the guard). Call before binding.
    ConnectionGuard(zmq::context_t& context, zmq::socket_t& socket, ConnectionCaps caps);
    ~ConnectionGuard();
    ConnectionGuard(const ConnectionGuard&) = delete;
    ConnectionGuard& operator=(const ConnectionGuard&) = delete;

    /// Connections refused so far (shut down on accept because a cap was reached).
    std::size_t refused() const { return refused_.load(); }
    /// Connections open now as the guard counts them.
    std::size_t open() const { return open_.load(); }

  private:
    void Run();
    void OnEvent(int event, int fd);

    zmq::socket_t& socket_;
    zmq::socket_t events_;
    ConnectionCaps caps_;
    std::map<int, std::string> peer_of_fd_;        ///< accepted connections: fd -> remote address
    std::map<std::string, std::size_t> per_peer_;  ///< remote address -> open connections
    std::atomic<bool> stop_{false};
    std::atomic<std::size_t> refused_{0};
    std::atomic<std::size_t> open_{0};
    std::thread thread_;
};

}  // namespace certislam::transport
