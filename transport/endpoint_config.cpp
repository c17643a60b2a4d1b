// Validation of endpoint configurations and the logical edge table.
#include "transport/endpoint_config.h"

#include <algorithm>
#include <stdexcept>

namespace certislam::transport {

bool IsSupportedAddress(const std::string& address) {
    for (const char* scheme : {"inproc://", "ipc://", "tcp://"}) {
        const std::string prefix = scheme;
        if (address.size() > prefix.size() && address.compare(0, prefix.size(), prefix) == 0) {
            return true;
        }
    }
    return false;
}

namespace {

/// Bound on EndpointConfig::shm_pool_segments.
constexpr std::size_t kMaxShmPoolSegments = 64;

[[noreturn]] void Reject(const EndpointConfig& config, const std::string& field,
                         const std::string& value, const std::string& rule) {
    throw std::invalid_argument("EndpointConfig(" + config.edge + ")." + field + " = '" + value +
                                "': " + rule);
}

}  // namespace

void EndpointConfig::Validate() const {
    if (edge.empty()) Reject(*this, "edge", edge, "must name the logical edge");
    if (bind.empty() && connect.empty()) {
        Reject(*this, "bind/connect", "", "at least one address is required");
    }
    for (const auto& address : bind) {
        if (!IsSupportedAddress(address)) {
            Reject(*this, "bind", address, "must start with inproc://, ipc:// or tcp://");
        }
    }
    for (const auto& address : connect) {
        if (!IsSupportedAddress(address)) {
            Reject(*this, "connect", address, "must start with inproc://, ipc:// or tcp://");
        }
    }
    if (max_queue_messages == 0) Reject(*this, "max_queue_messages", "0", "must be positive");
    if (max_queue_messages > 1'000'000'000) {
        Reject(*this, "max_queue_messages", std::to_string(max_queue_messages),
               "must be at most 1e9");
    }
    if (max_queue_bytes == 0) Reject(*this, "max_queue_bytes", "0", "must be positive");
    if (send_timeout_ms < -1) {
        Reject(*this, "send_timeout_ms", std::to_string(send_timeout_ms), "must be >= -1");
    }
    if (reconnect_interval_ms < 0) {
        Reject(*this, "reconnect_interval_ms", std::to_string(reconnect_interval_ms),
               "must be >= 0");
    }
    if (socket_buffer_bytes < 0) {
        Reject(*this, "socket_buffer_bytes", std::to_string(socket_buffer_bytes), "must be >= 0");
    }
    if (handshake_timeout_ms < 0) {
        Reject(*this, "handshake_timeout_ms", std::to_string(handshake_timeout_ms), "must be >= 0");
    }
    if (listen_backlog <= 0) {
        Reject(*this, "listen_backlog", std::to_string(listen_backlog), "must be > 0");
    }
    if (curve) curve->Validate();
    limits.Validate();
    if (shm_threshold_bytes == 0) Reject(*this, "shm_threshold_bytes", "0", "must be positive");
    if (shm_pool_segments > kMaxShmPoolSegments) {
        Reject(*this, "shm_pool_segments", std::to_string(shm_pool_segments),
               "must be at most " + std::to_string(kMaxShmPoolSegments));
    }
    try {
        shm.Validate();
    } catch (const std::invalid_argument& e) {
        Reject(*this, "shm", "", e.what());
    }
}

bool EndpointConfig::UsesShm() const {
    if (!shm_enabled) return false;
    const auto is_ipc = [](const std::string& address) { return address.rfind("ipc://", 0) == 0; };
    return std::all_of(bind.begin(), bind.end(), is_ipc) &&
           std::all_of(connect.begin(), connect.end(), is_ipc);
}

void EdgeTable::Add(const std::string& key, EndpointConfig config) {
    config.Validate();
    table_[key] = std::move(config);
}

const EndpointConfig& EdgeTable::Get(const std::string& key) const {
    const auto it = table_.find(key);
    if (it == table_.end()) {
        throw std::invalid_argument("edge '" + key + "' is not in the configuration");
    }
    return it->second;
}

std::vector<std::string> EdgeTable::Keys() const {
    std::vector<std::string> keys;
    for (const auto& [key, config] : table_) keys.push_back(key);
    return keys;
}

}  // namespace certislam::transport
