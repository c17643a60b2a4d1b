// Sizing a ZeroMQ context for many sockets: libzmq allows 1023 sockets per context by default,
// and every socket holds a file descriptor (its mailbox).
#pragma once

#include <zmq.hpp>

namespace certislam::transport {

/// Lets `context` open `sockets` sockets (call before its first socket): sets libzmq's
/// ZMQ_MAX_SOCKETS and raises the process's soft descriptor limit towards its hard limit when
/// needed. Throws std::runtime_error naming both numbers when the hard limit is too low.
void ReserveSockets(zmq::context_t& context, int sockets);

}  // namespace certislam::transport
