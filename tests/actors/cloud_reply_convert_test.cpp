// Cloud replies on the wire: the compact form (slam/io/cloud_compression.h) is the default, decodes
// to the same points within half a centimetre and is several times smaller than float32; the
// float32 form still decodes; a compact frame that lies about its count is dropped.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "actors/convert.h"

namespace certislam::actors {
namespace {

constexpr float kHalfStepM = 0.005f + 1e-5f;  // 1 cm quantisation, float slack
constexpr double kMinShrink = 2.0;            // random points compress worst

slam::PointCloudPtr RandomCloud(int n) {
    std::mt19937 rng(11);
    std::uniform_real_distribution<float> u(-40.f, 40.f);
    auto cloud = std::make_shared<slam::PointCloud>();
    for (int i = 0; i < n; ++i) cloud->emplace_back(u(rng), u(rng), u(rng) / 8.f);
    return cloud;
}

bool Less(const Eigen::Vector3f& a, const Eigen::Vector3f& b) {
    return std::lexicographical_compare(a.data(), a.data() + 3, b.data(), b.data() + 3);
}

v1::CloudReply Header() {
    v1::CloudReply reply;
    *reply.mutable_header() = MakeHeader(1, 7, 0);
    reply.set_request_id(42);
    return reply;
}

TEST(CloudReplyWire, CompactIsDefaultSmallerAndWithinHalfACentimetre) {
    const slam::PointCloudPtr cloud = RandomCloud(5000);
    const transport::Message compact = EncodeCloudReply(Header(), cloud);
    const transport::Message raw = EncodeCloudReply(Header(), cloud, CloudWire::kFloat32);
    ASSERT_EQ(compact.frames.size(), 1u);
    EXPECT_GE(static_cast<double>(raw.frames[0].size()) / compact.frames[0].size(), kMinShrink);
    v1::CloudReply reply;
    const auto back = DecodeCloudReply(compact, &reply);
    ASSERT_TRUE(back.has_value());
    EXPECT_EQ(reply.request_id(), 42u);
    EXPECT_EQ(reply.cloud().format(), v1::POINT_FORMAT_XYZ_CODEC);
    slam::PointCloud a = *cloud, b = **back;
    ASSERT_EQ(a.size(), b.size());
    // Morton order on the wire: compare as sets, each point within half a step of its own.
    const auto snapped = [](Eigen::Vector3f p) {  // as slam/io/cloud_compression.cpp rounds
        for (int k = 0; k < 3; ++k) {
            p[k] = static_cast<float>(std::lround(static_cast<double>(p[k]) / 0.01) * 0.01);
        }
        return p;
    };
    for (auto& p : a) p = snapped(p);
    std::sort(a.begin(), a.end(), Less);
    std::sort(b.begin(), b.end(), Less);
    for (size_t i = 0; i < a.size(); ++i) {
        EXPECT_LE((a[i] - b[i]).cwiseAbs().maxCoeff(), kHalfStepM) << i;
    }
    const auto raw_back = DecodeCloudReply(raw, nullptr);
    ASSERT_TRUE(raw_back.has_value());
    EXPECT_EQ(**raw_back, *cloud);  // float32 form: exact, order kept
}

TEST(CloudReplyWire, CompactFrameWithWrongCountIsDropped) {
    v1::CloudReply reply = Header();
    const transport::Message good = EncodeCloudReply(reply, RandomCloud(100));
    auto proto = transport::Unpack<v1::CloudReply>(good);
    ASSERT_TRUE(proto.has_value());
    proto->mutable_cloud()->set_point_count(101);
    const transport::Message lying = transport::Pack(*proto, good.frames);
    EXPECT_FALSE(DecodeCloudReply(lying, nullptr).has_value());
    proto->mutable_cloud()->set_point_count(100);
    std::vector<std::byte> cut(good.frames[0].data(), good.frames[0].data() + 20);
    const transport::Message truncated =
        transport::Pack(*proto, {transport::SharedBuffer::Adopt(std::move(cut))});
    EXPECT_FALSE(DecodeCloudReply(truncated, nullptr).has_value());
}

}  // namespace
}  // namespace certislam::actors
