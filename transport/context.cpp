#include "transport/context.h"

#include <sys/resource.h>

#include <algorithm>
#include <stdexcept>
#include <string>

namespace certislam::transport {
namespace {

constexpr int kLibzmqDefaultSockets = 1023;
constexpr rlim_t kSpareDescriptors = 256;  ///< files, tcp connections and libzmq's own

}  // namespace

void ReserveSockets(zmq::context_t& context, int sockets) {
    if (sockets <= kLibzmqDefaultSockets) return;
    const rlim_t needed = static_cast<rlim_t>(sockets) + kSpareDescriptors;
    rlimit limit{};
    if (getrlimit(RLIMIT_NOFILE, &limit) == 0 && limit.rlim_cur < needed) {
        if (limit.rlim_max != RLIM_INFINITY && limit.rlim_max < needed) {
            throw std::runtime_error(
                std::to_string(sockets) + " sockets need " + std::to_string(needed) +
                " file descriptors, but the hard limit is " + std::to_string(limit.rlim_max) +
                " (ulimit -Hn): raise it, or run fewer robots per process");
        }
        limit.rlim_cur = needed;
        if (setrlimit(RLIMIT_NOFILE, &limit) != 0) {
            throw std::runtime_error("could not raise the file descriptor limit to " +
                                     std::to_string(needed) + " for " + std::to_string(sockets) +
                                     " sockets");
        }
    }
    context.set(zmq::ctxopt::max_sockets, std::max(sockets, kLibzmqDefaultSockets));
}

}  // namespace certislam::transport
