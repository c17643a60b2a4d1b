// Connection caps from socket monitor events (zmq_socket_monitor, libzmq 4.x event format: frame
// 1 = uint16 event + uint32 value, the value being the connection's fd for the events used here).
#include "transport/connection_guard.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>

#include <array>
#include <cstdint>
#include <cstring>

namespace certislam::transport {
namespace {

// The remote address of a connected socket ("" when it cannot be told).
std::string PeerAddress(int fd) {
    sockaddr_storage addr{};
    socklen_t len = sizeof(addr);
    if (getpeername(fd, reinterpret_cast<sockaddr*>(&addr), &len) != 0) return "";
    std::array<char, INET6_ADDRSTRLEN> text{};
    const void* raw =
        addr.ss_family == AF_INET6
            ? static_cast<const void*>(&reinterpret_cast<sockaddr_in6*>(&addr)->sin6_addr)
            : static_cast<const void*>(&reinterpret_cast<sockaddr_in*>(&addr)->sin_addr);
    if (inet_ntop(addr.ss_family, raw, text.data(), text.size()) == nullptr) return "";
    return text.data();
}

}  // namespace

ConnectionGuard::ConnectionGuard(zmq::context_t& context, zmq::socket_t& socket,
                                 ConnectionCaps caps)
    : socket_(socket), events_(context, zmq::socket_type::pair), caps_(caps) {
    const std::string address =
        "inproc://certislam.guard." + std::to_string(reinterpret_cast<std::uintptr_t>(this));
    if (zmq_socket_monitor(socket_.handle(), address.c_str(),
                           ZMQ_EVENT_ACCEPTED | ZMQ_EVENT_DISCONNECTED | ZMQ_EVENT_CLOSED) != 0) {
        throw zmq::error_t();
    }
    events_.set(zmq::sockopt::linger, 0);
    events_.set(zmq::sockopt::rcvhwm, 0);  // never drop an event: a lost DISCONNECTED leaks a slot
    events_.connect(address);
    thread_ = std::thread([this] { Run(); });
}

ConnectionGuard::~ConnectionGuard() {
    stop_ = true;
    thread_.join();
    zmq_socket_monitor(socket_.handle(), nullptr, 0);
}

void ConnectionGuard::Run() {
    zmq::pollitem_t item{events_.handle(), 0, ZMQ_POLLIN, 0};
    while (!stop_) {
        zmq::poll(&item, 1, std::chrono::milliseconds(50));
        if (!(item.revents & ZMQ_POLLIN)) continue;
        zmq::message_t head, address;
        if (!events_.recv(head, zmq::recv_flags::dontwait)) continue;
        if (head.more()) (void)events_.recv(address, zmq::recv_flags::dontwait);
        if (head.size() < 6) continue;
        std::uint16_t event = 0;
        std::uint32_t value = 0;
        std::memcpy(&event, head.data(), 2);
        std::memcpy(&value, static_cast<const char*>(head.data()) + 2, 4);
        OnEvent(event, static_cast<int>(value));
    }
}

void ConnectionGuard::OnEvent(int event, int fd) {
    if (event == ZMQ_EVENT_ACCEPTED) {
        const std::string peer = PeerAddress(fd);
        if ((caps_.max_total > 0 && peer_of_fd_.size() >= caps_.max_total) ||
            (caps_.max_per_peer > 0 && per_peer_[peer] >= caps_.max_per_peer)) {
            // Still libzmq's descriptor: shutdown (not close) makes it see end of stream.
            ::shutdown(fd, SHUT_RDWR);
            refused_.fetch_add(1);
            return;
        }
        peer_of_fd_[fd] = peer;
        ++per_peer_[peer];
    } else {  // DISCONNECTED or CLOSED: the fd is gone (each is seen once per tracked fd)
        const auto it = peer_of_fd_.find(fd);
        if (it == peer_of_fd_.end()) return;
        if (--per_peer_[it->second] == 0) per_peer_.erase(it->second);
        peer_of_fd_.erase(it);
    }
    open_ = peer_of_fd_.size();
}

}  // namespace certislam::transport
