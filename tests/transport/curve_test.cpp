// CURVE + ZAP over real tcp loopback sockets: a listed robot key delivers, an unlisted one
// delivers nothing, a listed robot cannot speak for another; key files round-trip.
#include "transport/curve.h"

#include <gtest/gtest.h>

#include <fstream>

#include "tests/transport/test_util.h"
#include "transport/endpoint.h"

namespace certislam::transport {
namespace {

using testing::Config;
using testing::TestMessage;

constexpr std::chrono::milliseconds kTimeout{5000};
constexpr std::chrono::milliseconds kQuiet{300};  // how long "nothing arrives" is watched

CurveConfig Server(const KeyPair& keys) {
    CurveConfig curve;
    curve.server = true;
    curve.own = keys;
    return curve;
}

CurveConfig Client(const KeyPair& keys, const KeyPair& server) {
    CurveConfig curve;
    curve.own = keys;
    curve.server_public_z85 = server.public_z85;
    return curve;
}

// Receives until the authenticator has denied at least `denials` handshakes (poll, no sleep).
std::vector<Message> ReceiveUntilDenied(Endpoint& endpoint, const ZapAuthenticator& zap,
                                        std::uint64_t denials) {
    std::vector<Message> got;
    const auto deadline = std::chrono::steady_clock::now() + kTimeout;
    while (zap.denied() < denials && std::chrono::steady_clock::now() < deadline) {
        if (auto message = endpoint.Receive(std::chrono::milliseconds(10))) {
            got.push_back(std::move(*message));
        }
    }
    while (auto message = endpoint.Receive(kQuiet)) got.push_back(std::move(*message));
    return got;
}

class Curve : public ::testing::Test {
  protected:
    zmq::context_t context_;
    KeyPair server_keys_ = GenerateKeyPair();
    KeyPair listed_keys_ = GenerateKeyPair();
    KeyPair unlisted_keys_ = GenerateKeyPair();
    ZapAuthenticator zap_{context_, {{listed_keys_.public_z85, 1}}};
};

TEST_F(Curve, ListedClientDeliversAndUnlistedClientDeliversNothing) {
    auto server_config = Config(Role::kPull, "tcp://127.0.0.1:*", true);
    server_config.curve = Server(server_keys_);
    Endpoint server(context_, server_config);
    const std::string address = server.bound_addresses()[0];

    auto intruder_config = Config(Role::kPush, address, false);
    intruder_config.curve = Client(unlisted_keys_, server_keys_);
    intruder_config.send_timeout_ms = 0;
    Endpoint intruder(context_, intruder_config);
    intruder.Send(TestMessage(666, 1));  // claims robot 1, but its key is not listed

    auto robot_config = Config(Role::kPush, address, false);
    robot_config.curve = Client(listed_keys_, server_keys_);
    Endpoint robot(context_, robot_config);
    ASSERT_EQ(robot.Send(TestMessage(1, 1)), SendStatus::kSent);

    const std::vector<Message> got = ReceiveUntilDenied(server, zap_, 1);
    ASSERT_EQ(got.size(), 1u);
    EXPECT_EQ(got[0].envelope.header().sequence(), 1u);
    EXPECT_EQ(got[0].user_id, "1");
    EXPECT_GE(zap_.denied(), 1u);
    EXPECT_GE(zap_.accepted(), 1u);
}

TEST_F(Curve, ListedRobotCannotSpeakForAnotherRobot) {
    auto server_config = Config(Role::kPull, "tcp://127.0.0.1:*", true);
    server_config.curve = Server(server_keys_);
    Endpoint server(context_, server_config);
    auto robot_config = Config(Role::kPush, server.bound_addresses()[0], false);
    robot_config.curve = Client(listed_keys_, server_keys_);
    Endpoint robot(context_, robot_config);
    ASSERT_EQ(robot.Send(TestMessage(1, 2)), SendStatus::kSent);  // robot 1's key, robot 2's id
    ASSERT_EQ(robot.Send(TestMessage(2, 1)), SendStatus::kSent);
    const auto message = server.Receive(kTimeout);
    ASSERT_TRUE(message.has_value());
    EXPECT_EQ(message->envelope.header().sequence(), 2u);
    EXPECT_EQ(server.counters().dropped_unauthorized, 1u);
}

TEST_F(Curve, UnlistedSubscriberNeverJoinsAnEncryptedStream) {
    auto pub_config = Config(Role::kPublisher, "tcp://127.0.0.1:*", true);
    pub_config.curve = Server(server_keys_);
    Endpoint publisher(context_, pub_config);
    const std::string address = publisher.bound_addresses()[0];
    auto listed_config = Config(Role::kSubscriber, address, false);
    listed_config.curve = Client(listed_keys_, server_keys_);
    auto unlisted_config = Config(Role::kSubscriber, address, false);
    unlisted_config.curve = Client(unlisted_keys_, server_keys_);
    Endpoint unlisted(context_, unlisted_config);
    Endpoint listed(context_, listed_config);

    ASSERT_TRUE(publisher.WaitForSubscribers(1, kTimeout));
    ASSERT_TRUE(listed.WaitReady(kTimeout));
    ASSERT_EQ(publisher.Send(TestMessage(5)), SendStatus::kSent);
    ASSERT_TRUE(listed.Receive(kTimeout).has_value());
    EXPECT_FALSE(unlisted.WaitReady(kQuiet));
    EXPECT_FALSE(unlisted.Receive(kQuiet).has_value());
    EXPECT_EQ(publisher.subscribers(), 1u);
}

TEST(CurveKeys, KeyFilesRoundTripAndBadFilesNameFileAndLine) {
    testing::TempDir dir;
    const KeyPair keys = GenerateKeyPair();
    EXPECT_TRUE(IsValidZ85Key(keys.public_z85));
    EXPECT_NE(keys.public_z85, keys.secret_z85);
    const std::string prefix = dir.path() + "/robot1";
    SaveKeyPair(keys, prefix);
    const KeyPair loaded = LoadKeyPair(prefix + ".key");
    EXPECT_EQ(loaded.public_z85, keys.public_z85);
    EXPECT_EQ(loaded.secret_z85, keys.secret_z85);
    EXPECT_EQ(LoadPublicKey(prefix + ".pub"), keys.public_z85);

    const std::string bad = dir.path() + "/bad.key";
    std::ofstream(bad) << "# comment\npublic not-a-key\n";
    try {
        LoadKeyPair(bad);
        FAIL() << "bad key accepted";
    } catch (const std::runtime_error& e) {
        EXPECT_NE(std::string(e.what()).find(bad + ":2"), std::string::npos) << e.what();
    }
    EXPECT_THROW(LoadKeyPair(dir.path() + "/missing.key"), std::runtime_error);
    CurveConfig config;
    config.own = keys;
    EXPECT_THROW(config.Validate(), std::invalid_argument);  // client without server key
}

}  // namespace
}  // namespace certislam::transport
