// Helpers shared by the transport tests: addresses per transport kind and test messages.
#pragma once

#include <stdlib.h>
#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <string>

#include "certislam/v1/keyframe.pb.h"
#include "transport/endpoint.h"

namespace certislam::transport::testing {

/// The transports a logical edge can be bound to.
enum class Kind { kInproc, kIpc, kTcp };

inline const char* Name(Kind kind) {
    switch (kind) {
        case Kind::kInproc:
            return "inproc";
        case Kind::kIpc:
            return "ipc";
        case Kind::kTcp:
            return "tcp";
    }
    return "?";
}

/// A temporary directory removed at scope exit (for ipc:// socket files).
class TempDir {
  public:
    TempDir() {
        std::string pattern =
            (std::filesystem::temp_directory_path() / "certislam-transport-XXXXXX").string();
        path_ = mkdtemp(pattern.data());
    }
    ~TempDir() { std::filesystem::remove_all(path_); }
    const std::string& path() const { return path_; }

  private:
    std::string path_;
};

/// A unique bind address of the given kind (tcp: loopback with an ephemeral port).
inline std::string BindAddress(Kind kind, const TempDir& dir) {
    static std::atomic<int> counter{0};
    const std::string name = "edge" + std::to_string(counter++);
    switch (kind) {
        case Kind::kInproc:
            return "inproc://" + name + "-" + std::to_string(getpid());
        case Kind::kIpc:
            return "ipc://" + dir.path() + "/" + name;
        case Kind::kTcp:
            return "tcp://127.0.0.1:*";
    }
    return {};
}

/// A small keyframe message with the given sequence number and robot id.
inline Message TestMessage(std::uint64_t sequence, std::uint32_t robot_id = 1,
                           std::vector<SharedBuffer> frames = {}) {
    v1::Keyframe keyframe;
    keyframe.mutable_header()->set_robot_id(robot_id);
    keyframe.mutable_header()->set_sequence(sequence);
    keyframe.mutable_pose_id()->set_index(sequence);
    return Pack(keyframe, std::move(frames));
}

/// Endpoint config with one bind or connect address.
inline EndpointConfig Config(Role role, const std::string& address, bool bind,
                             Delivery delivery = Delivery::kReliable) {
    EndpointConfig config;
    config.edge = "test";
    config.role = role;
    (bind ? config.bind : config.connect).push_back(address);
    config.delivery = delivery;
    return config;
}

}  // namespace certislam::transport::testing
