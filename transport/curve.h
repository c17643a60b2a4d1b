// CURVE security for tcp:// edges: key pairs, key files, and a ZAP handler with an allow-list.
#pragma once

#include <atomic>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <thread>
#include <zmq.hpp>

namespace certislam::transport {

/// A CURVE key pair, each key as 40 Z85 characters.
struct KeyPair {
    std::string public_z85;  ///< shared with peers (allow-lists name it)
    std::string secret_z85;  ///< never leaves the robot
};

/// A fresh random key pair (zmq_curve_keypair).
KeyPair GenerateKeyPair();

/// True when text is a 40-character Z85 encoding of a 32-byte key.
bool IsValidZ85Key(std::string_view text);

/// Writes PREFIX.pub (public key, one line) and PREFIX.key ("public <z85>" and "secret <z85>"
/// lines, mode 0600). Throws std::runtime_error naming the file on failure.
void SaveKeyPair(const KeyPair& keys, const std::string& prefix);

/// Reads a PREFIX.key file written by SaveKeyPair. Throws std::runtime_error naming file:line.
KeyPair LoadKeyPair(const std::string& key_path);

/// Reads a public key from a PREFIX.pub file (or the public line of a .key file).
/// Throws std::runtime_error naming file:line.
std::string LoadPublicKey(const std::string& path);

/// CURVE settings of one endpoint. The server side authenticates clients through the
/// context's ZapAuthenticator; the client side must know the server's public key.
struct CurveConfig {
    bool server = false;                   ///< true on the side that accepts (usually the binder)
    KeyPair own;                           ///< this endpoint's key pair
    std::string server_public_z85;         ///< client only: the server's public key
    std::string zap_domain = "certislam";  ///< ZAP domain sent to the authenticator

    /// Throws std::invalid_argument naming the field, value and rule.
    void Validate() const;
};

/// Applies CURVE options to a socket (before bind/connect).
void ApplyCurve(zmq::socket_t& socket, const CurveConfig& curve);

/// The ZAP handler of one ZeroMQ context: accepts a CURVE client only when its public key is on
/// the allow-list, and gives it the listed robot id as ZAP user id (decimal, e.g. "3"), which
/// receivers see as Message::user_id; a CURVE server endpoint drops (and counts) messages whose
/// header claims another robot id. Everything else (unlisted key, other mechanism) is denied and
/// counted. Create it before any CURVE server socket of the context binds; at most one per context.
class ZapAuthenticator {
  public:
    /// Binds inproc://zeromq.zap.01 in the context and starts the handler thread.
    /// allowed maps public key (Z85) -> robot id. Throws std::invalid_argument on a bad key.
    ZapAuthenticator(zmq::context_t& context, std::map<std::string, std::uint32_t> allowed);
    /// Stops the handler thread.
    ~ZapAuthenticator();
    ZapAuthenticator(const ZapAuthenticator&) = delete;
    ZapAuthenticator& operator=(const ZapAuthenticator&) = delete;

    /// Adds or replaces one allowed key (thread-safe).
    void Allow(const std::string& public_z85, std::uint32_t robot_id);
    /// Removes a key (thread-safe); later handshakes with it are denied.
    void Revoke(const std::string& public_z85);

    /// Handshakes accepted so far.
    std::uint64_t accepted() const { return accepted_.load(); }
    /// Handshakes denied so far (unlisted key or non-CURVE mechanism).
    std::uint64_t denied() const { return denied_.load(); }

  private:
    void Run();
    void HandleRequest();

    zmq::socket_t handler_;  // REP on inproc://zeromq.zap.01
    zmq::socket_t stop_rx_;  // PAIR: the destructor signals the thread through it
    zmq::socket_t stop_tx_;
    std::mutex mutex_;
    std::map<std::string, std::uint32_t> allowed_;
    std::atomic<std::uint64_t> accepted_{0};
    std::atomic<std::uint64_t> denied_{0};
    std::thread thread_;
};

}  // namespace certislam::transport
