// The transport section of a YAML configuration: the same code runs an edge bound by the file to
// inproc://, ipc:// or tcp://; key files are read; every error names file:line and the field.
#include "transport/transport_config_io.h"

#include <gtest/gtest.h>

#include <fstream>

#include "tests/transport/test_util.h"
#include "transport/endpoint.h"

namespace certislam::transport {
namespace {

constexpr std::chrono::milliseconds kTimeout{5000};

// The code of an actor: knows the edge names only, never the addresses.
std::vector<std::uint64_t> SendThroughEdge(zmq::context_t& context, const EdgeTable& edges) {
    Endpoint in(context, edges.Get("poses/pull"));
    Endpoint out(context, edges.Get("poses/push"));
    for (std::uint64_t i = 0; i < 5; ++i)
        EXPECT_EQ(out.Send(testing::TestMessage(i)), SendStatus::kSent);
    std::vector<std::uint64_t> got;
    while (got.size() < 5) {
        auto message = in.Receive(kTimeout);
        if (!message) break;
        got.push_back(message->envelope.header().sequence());
    }
    return got;
}

// A loopback address whose port was free a moment ago (the file must name a fixed port).
std::string FreeTcpAddress() {
    zmq::context_t context;
    zmq::socket_t probe(context, zmq::socket_type::pull);
    probe.set(zmq::sockopt::linger, 0);
    probe.bind("tcp://127.0.0.1:*");
    return probe.get(zmq::sockopt::last_endpoint);
}

class TransportConfigFile : public ::testing::TestWithParam<testing::Kind> {};

TEST_P(TransportConfigFile, BindsTheSameEdgeToTheAddressTheFileNames) {
    testing::TempDir dir;
    const std::string bind = GetParam() == testing::Kind::kTcp
                                 ? FreeTcpAddress()
                                 : testing::BindAddress(GetParam(), dir);
    const std::string yaml =
        "robot_id: 2\nnode_name: robot2/solver\nedges:\n"
        "  poses/pull: {role: pull, bind: " +
        bind +
        ", delivery: reliable,\n"
        "               max_queue_messages: 7, max_queue_bytes: 4096, shm: true,\n"
        "               shm_threshold_bytes: 2048, shm_pool_segments: 2,\n"
        "               socket_buffer_bytes: 262144}\n"
        "  poses/push: {role: push, connect: [" +
        bind +
        "]}\n"
        "other_layer: {ignored: true}\n";
    const TransportFileConfig file = ParseTransportConfig(yaml, dir.path(), "robot2.yaml");
    EXPECT_EQ(file.robot_id, 2u);
    EXPECT_EQ(file.edges.Keys(), (std::vector<std::string>{"poses/pull", "poses/push"}));
    const EndpointConfig& pull = file.edges.Get("poses/pull");
    EXPECT_EQ(pull.edge, "poses");
    EXPECT_EQ(pull.role, Role::kPull);
    EXPECT_EQ(pull.max_queue_messages, 7u);
    EXPECT_EQ(pull.max_queue_bytes, 4096u);
    EXPECT_EQ(pull.node_name, "robot2/solver");
    EXPECT_TRUE(pull.shm_enabled);
    EXPECT_EQ(pull.shm_threshold_bytes, 2048u);
    EXPECT_EQ(pull.shm_pool_segments, 2u);
    EXPECT_EQ(pull.socket_buffer_bytes, 262144);
    EXPECT_EQ(pull.UsesShm(), GetParam() == testing::Kind::kIpc);
    zmq::context_t context;
    EXPECT_EQ(SendThroughEdge(context, file.edges), (std::vector<std::uint64_t>{0, 1, 2, 3, 4}));
}

INSTANTIATE_TEST_SUITE_P(EachTransport, TransportConfigFile,
                         ::testing::Values(testing::Kind::kInproc, testing::Kind::kIpc,
                                           testing::Kind::kTcp),
                         [](const auto& info) { return std::string(testing::Name(info.param)); });

TEST(TransportConfigFile, ReadsKeyFilesRelativeToTheFileAndBuildsTheAllowList) {
    testing::TempDir dir;
    std::filesystem::create_directories(dir.path() + "/keys");
    const KeyPair own = GenerateKeyPair();
    const KeyPair peer = GenerateKeyPair();
    SaveKeyPair(own, dir.path() + "/keys/robot1");
    SaveKeyPair(peer, dir.path() + "/keys/robot2");
    const std::string path = dir.path() + "/robot1.yaml";
    std::ofstream(path)
        << "robot_id: 1\n"
           "keys:\n"
           "  own: keys/robot1.key\n"
           "  allow:\n"
           "    2: keys/robot2.pub\n"
           "edges:\n"
           "  rbcd/router: {role: router, bind: 'tcp://127.0.0.1:*', curve: server}\n"
           "  rbcd/dealer: {role: dealer, connect: 'tcp://127.0.0.1:5601',\n"
           "                curve: client, server_key: keys/robot2.pub}\n";
    const TransportFileConfig file = LoadTransportConfig(path);
    ASSERT_TRUE(file.own_keys.has_value());
    EXPECT_EQ(file.own_keys->secret_z85, own.secret_z85);
    EXPECT_EQ(file.allow_list, (std::map<std::string, std::uint32_t>{{peer.public_z85, 2}}));
    const auto& router = file.edges.Get("rbcd/router");
    ASSERT_TRUE(router.curve.has_value());
    EXPECT_TRUE(router.curve->server);
    EXPECT_EQ(router.curve->own.public_z85, own.public_z85);
    const auto& dealer = file.edges.Get("rbcd/dealer");
    ASSERT_TRUE(dealer.curve.has_value());
    EXPECT_FALSE(dealer.curve->server);
    EXPECT_EQ(dealer.curve->server_public_z85, peer.public_z85);
}

// Parsing `yaml` fails with a message that contains every one of `needles`.
void ExpectError(const std::string& yaml, const std::vector<std::string>& needles) {
    try {
        ParseTransportConfig(yaml, "/nonexistent", "bad.yaml");
        ADD_FAILURE() << "accepted:\n" << yaml;
    } catch (const std::runtime_error& e) {
        for (const auto& needle : needles) {
            EXPECT_NE(std::string(e.what()).find(needle), std::string::npos)
                << e.what() << " lacks " << needle;
        }
    }
}

TEST(TransportConfigFile, ErrorsNameTheFileLineAndField) {
    ExpectError("edges:\n  a/pull: {role: pull, bind: inproc://a, colour: red}\n",
                {"bad.yaml:2", "unknown field 'colour'"});
    ExpectError("edges:\n  a/pull:\n    role: sink\n    bind: inproc://a\n",
                {"bad.yaml:3", "role = 'sink'"});
    ExpectError("edges:\n  a/pull: {role: pull, bind: udp://x}\n", {"bad.yaml:2", "bind"});
    ExpectError("edges:\n  a/pull: {role: pull, bind: inproc://a, max_queue_messages: many}\n",
                {"bad.yaml:2", "max_queue_messages = 'many'"});
    ExpectError("edges:\n  a/pull: {role: pull, bind: inproc://a, max_queue_bytes: 0}\n",
                {"bad.yaml:2", "max_queue_bytes"});
    ExpectError("edges:\n  a/pull: {role: pull, bind: 'tcp://127.0.0.1:*', curve: server}\n",
                {"bad.yaml:2", "keys.own"});
    ExpectError("robot_id: 1\nkeys:\n  own: robot1.key\n",
                {"bad.yaml:3", "keys.own", "/nonexistent/robot1.key"});
    ExpectError("edges: [\n", {"bad.yaml:"});
    ExpectError("edges:\n  a/pull: {role: pull, bind: ipc:///tmp/a, shm_threshold_bytes: 0}\n",
                {"bad.yaml:2", "shm_threshold_bytes"});
    ExpectError("edges:\n  a/pull: {role: pull, bind: ipc:///tmp/a, shm: maybe}\n",
                {"bad.yaml:2", "shm = 'maybe'"});
}

}  // namespace
}  // namespace certislam::transport
