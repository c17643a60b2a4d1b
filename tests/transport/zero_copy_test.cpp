// Zero-copy: over inproc a large buffer moves as a handle (same address, never copied) and is
// freed when its last holder releases it; across processes' transports the bytes arrive intact.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <numeric>

#include "tests/transport/test_util.h"
#include "transport/buffer.h"
#include "transport/endpoint.h"

namespace certislam::transport {
namespace {

using testing::Config;
using testing::Kind;
using testing::TestMessage;

constexpr std::chrono::milliseconds kTimeout{5000};

SharedBuffer Pattern(std::size_t bytes) {
    std::vector<std::byte> data(bytes);
    for (std::size_t i = 0; i < bytes; ++i) data[i] = static_cast<std::byte>(i * 131 % 251);
    return SharedBuffer::Adopt(std::move(data));
}

TEST(SharedBuffer, CopiesShareStorageAndZmqFramesHoldAReference) {
    SharedBuffer buffer = Pattern(1 << 20);
    const std::weak_ptr<const void> watch = buffer.Watch();
    EXPECT_EQ(buffer.use_count(), 1);
    {
        zmq::message_t frame = ToZmqFrame(buffer);
        EXPECT_EQ(frame.data(), static_cast<const void*>(buffer.data()));
        EXPECT_EQ(buffer.use_count(), 2);
    }
    EXPECT_EQ(buffer.use_count(), 1);
    buffer = SharedBuffer();
    EXPECT_TRUE(watch.expired());
}

class ZeroCopyInproc : public ::testing::TestWithParam<std::size_t> {};

TEST_P(ZeroCopyInproc, ReceiverReadsTheSendersBytesAndTheLastReleaseFreesThem) {
    zmq::context_t context;
    testing::TempDir dir;
    const std::string address = testing::BindAddress(Kind::kInproc, dir);
    Endpoint publisher(context, Config(Role::kPublisher, address, true));
    Endpoint subscriber(context, Config(Role::kSubscriber, address, false));
    ASSERT_TRUE(publisher.WaitForSubscribers(1, kTimeout));
    ASSERT_TRUE(subscriber.WaitReady(kTimeout));

    SharedBuffer cloud = Pattern(GetParam());
    const std::byte* sender_address = cloud.data();
    const std::weak_ptr<const void> watch = cloud.Watch();
    const auto start = std::chrono::steady_clock::now();
    ASSERT_EQ(publisher.Send(TestMessage(1, 1, {cloud})), SendStatus::kSent);
    auto received = subscriber.Receive(kTimeout);
    const auto elapsed = std::chrono::steady_clock::now() - start;
    ASSERT_TRUE(received.has_value());
    ASSERT_EQ(received->frames.size(), 1u);
    EXPECT_EQ(received->frames[0].data(), sender_address) << "the bytes were copied";
    EXPECT_EQ(received->frames[0].size(), GetParam());
    std::printf("inproc %zu bytes one-way (send+receive, one thread): %.1f us\n", GetParam(),
                std::chrono::duration<double, std::micro>(elapsed).count());

    cloud = SharedBuffer();
    EXPECT_FALSE(watch.expired()) << "the receiver still holds the buffer";
    received.reset();
    EXPECT_TRUE(watch.expired()) << "the buffer outlived its last holder";
}

INSTANTIATE_TEST_SUITE_P(Sizes, ZeroCopyInproc,
                         ::testing::Values(std::size_t{1} << 20, std::size_t{10} << 20,
                                           std::size_t{100} << 20),
                         [](const auto& info) { return std::to_string(info.param >> 20) + "MB"; });

class BytesAcrossTransports : public ::testing::TestWithParam<Kind> {};

TEST_P(BytesAcrossTransports, LargeFrameArrivesIntactInItsOwnFrame) {
    zmq::context_t context;
    testing::TempDir dir;
    Endpoint pull(context, Config(Role::kPull, testing::BindAddress(GetParam(), dir), true));
    Endpoint push(context, Config(Role::kPush, pull.bound_addresses()[0], false));
    const SharedBuffer cloud = Pattern(std::size_t{10} << 20);
    const Message sent = TestMessage(3, 1, {cloud});
    EXPECT_LT(sent.envelope.ByteSizeLong(), 128u) << "binary data must not be inside protobuf";
    ASSERT_EQ(push.Send(sent), SendStatus::kSent);
    const auto received = pull.Receive(kTimeout);
    ASSERT_TRUE(received.has_value());
    ASSERT_EQ(received->frames.size(), 1u);
    ASSERT_EQ(received->frames[0].size(), cloud.size());
    EXPECT_EQ(std::memcmp(received->frames[0].data(), cloud.data(), cloud.size()), 0);
}

INSTANTIATE_TEST_SUITE_P(Transports, BytesAcrossTransports,
                         ::testing::Values(Kind::kInproc, Kind::kIpc, Kind::kTcp),
                         [](const auto& info) { return testing::Name(info.param); });

}  // namespace
}  // namespace certislam::transport
