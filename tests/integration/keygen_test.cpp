// `certislam keygen`: the files it writes are the ones a configuration names, and with them a
// listed robot delivers over CURVE on a real tcp socket while an unlisted robot delivers nothing.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "certislam/v1/keyframe.pb.h"
#include "tests/integration/shell.h"
#include "transport/endpoint.h"
#include "transport/transport_config_io.h"

namespace certislam {
namespace {

using testing::Shell;
using transport::Endpoint;

constexpr std::chrono::milliseconds kTimeout{5000};
constexpr std::chrono::milliseconds kQuiet{300};  // how long "nothing arrives" is watched

class Keygen : public ::testing::Test {
  protected:
    void SetUp() override {
        dir_ = std::filesystem::temp_directory_path() /
               ("certislam-keygen-" + std::to_string(getpid()));
        std::filesystem::create_directories(dir_ / "keys");
    }
    void TearDown() override { std::filesystem::remove_all(dir_); }

    // Runs the real command; returns its JSON report.
    nlohmann::json RunKeygen(const std::string& name) {
        const auto result = Shell(std::string(CERTISLAM_BINARY) + " keygen --json --out " +
                                  (dir_ / "keys" / name).string());
        EXPECT_EQ(result.exit_code, 0) << result.out;
        return nlohmann::json::parse(result.out);
    }

    // Writes a configuration file and reads it back.
    transport::TransportFileConfig Config(const std::string& name, const std::string& yaml) {
        const auto path = dir_ / name;
        std::ofstream(path) << yaml;
        return transport::LoadTransportConfig(path.string());
    }

    std::filesystem::path dir_;
};

TEST_F(Keygen, WritesAPublicFileAndASecretFileReadableOnlyByItsOwner) {
    const auto report = RunKeygen("robot1");
    const std::string pub = report.at("public_key_file");
    const std::string key = report.at("secret_key_file");
    EXPECT_EQ(pub, (dir_ / "keys" / "robot1.pub").string());
    EXPECT_EQ(transport::LoadPublicKey(pub), report.at("public_z85"));
    const transport::KeyPair pair = transport::LoadKeyPair(key);
    EXPECT_EQ(pair.public_z85, report.at("public_z85"));
    EXPECT_TRUE(transport::IsValidZ85Key(pair.secret_z85));
    struct stat info {};
    ASSERT_EQ(stat(key.c_str(), &info), 0);
    EXPECT_EQ(info.st_mode & 0777, 0600u);
    EXPECT_NE(RunKeygen("robot2").at("public_z85"), report.at("public_z85"));  // fresh every time

    const auto bad = Shell(std::string(CERTISLAM_BINARY) + " keygen --out /nonexistent/dir/r 2>&1");
    EXPECT_NE(bad.exit_code, 0) << bad.out;
}

TEST_F(Keygen, ExistingKeyIsKeptUnlessForced) {
    const std::string prefix = (dir_ / "keys" / "robot1").string();
    const std::string first = RunKeygen("robot1").at("public_z85");
    const auto again = Shell(std::string(CERTISLAM_BINARY) + " keygen --out " + prefix + " 2>&1");
    EXPECT_EQ(again.exit_code, 1) << again.out;
    EXPECT_NE(again.out.find("robot1.pub exists"), std::string::npos) << again.out;
    EXPECT_EQ(transport::LoadKeyPair(prefix + ".key").public_z85, first);  // untouched
    const auto forced =
        Shell(std::string(CERTISLAM_BINARY) + " keygen --force --json --out " + prefix);
    ASSERT_EQ(forced.exit_code, 0) << forced.out;
    const std::string second = nlohmann::json::parse(forced.out).at("public_z85");
    EXPECT_NE(second, first);
    EXPECT_EQ(transport::LoadKeyPair(prefix + ".key").public_z85, second);
}

TEST_F(Keygen, KeysNamedInConfigurationLetAListedRobotDeliverAndNoOtherRobot) {
    for (const char* robot : {"robot1", "robot2", "robot3"}) RunKeygen(robot);
    zmq::context_t server_context;
    const auto server =
        Config("robot1.yaml",
               "robot_id: 1\n"
               "keys: {own: keys/robot1.key, allow: {2: keys/robot2.pub}}\n"
               "edges:\n"
               "  loops/pull: {role: pull, bind: 'tcp://127.0.0.1:*', curve: server}\n");
    transport::ZapAuthenticator zap(server_context, server.allow_list);
    Endpoint in(server_context, server.edges.Get("loops/pull"));
    const std::string address = in.bound_addresses().front();

    // Robot 3 has valid keys of its own, but robot 1's allow-list does not name them.
    for (const std::uint32_t robot : {3u, 2u}) {
        const std::string name = "robot" + std::to_string(robot);
        const auto client = Config(
            name + ".yaml", "robot_id: " + std::to_string(robot) + "\nkeys: {own: keys/" + name +
                                ".key}\n"
                                "edges:\n  loops/push: {role: push, connect: '" +
                                address +
                                "', curve: client, "
                                "server_key: keys/robot1.pub, "
                                "send_timeout_ms: 0}\n");
        zmq::context_t context;
        Endpoint out(context, client.edges.Get("loops/push"));
        v1::Keyframe keyframe;
        keyframe.mutable_header()->set_robot_id(robot);
        const auto deadline = std::chrono::steady_clock::now() + kTimeout;
        std::optional<transport::Message> got;
        // Robot 3: until the handshake is denied; robot 2: until its message arrives.
        while (std::chrono::steady_clock::now() < deadline && !got &&
               (robot == 2 || zap.denied() == 0)) {
            out.Send(transport::Pack(keyframe));  // not connected yet: kBackpressure, retried
            got = in.Receive(std::chrono::milliseconds(10));
        }
        if (robot == 3) {
            EXPECT_GE(zap.denied(), 1u);
            EXPECT_FALSE(got.has_value());
            EXPECT_FALSE(in.Receive(kQuiet).has_value());
        } else {
            ASSERT_TRUE(got.has_value());
            EXPECT_EQ(got->envelope.header().robot_id(), 2u);
            EXPECT_EQ(got->user_id, "2");
        }
    }
    EXPECT_EQ(zap.accepted(), 1u);
}

}  // namespace
}  // namespace certislam
