// The decoders of the solver status and of the distributed certificate round's messages: a
// message a certifier sends decodes to what it holds; round 0, non-finite values, a value count
// that does not match the ids, or ids beyond an int decode to nothing.
#include <gtest/gtest.h>

#include <limits>

#include "actors/convert.h"

namespace certislam::actors {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

v1::CertificateVector MakeVector() {
    v1::CertificateVector v;
    *v.mutable_header() = MakeHeader(2, 1, 0);
    v.set_round(77);
    v.set_step(3);
    v.set_block_size(kCertificateBlock);
    for (int i = 0; i < 2; ++i) *v.add_pose_ids() = ToProto(slam::PoseId{2, i});
    for (int i = 0; i < 8; ++i) v.add_values(0.5 * i);
    return v;
}

TEST(ConvertCertificate, VectorDecodesToItsIdsAndValues) {
    const auto vector = FromProto(MakeVector());
    ASSERT_TRUE(vector.has_value());
    EXPECT_EQ(vector->round, 77u);
    EXPECT_EQ(vector->robot, 2);
    EXPECT_EQ(vector->step, 3);
    ASSERT_EQ(vector->ids.size(), 2u);
    EXPECT_EQ(vector->ids[1], (slam::PoseId{2, 1}));
    ASSERT_EQ(vector->values.size(), 8);
    EXPECT_EQ(vector->values[7], 3.5);
}

TEST(ConvertCertificate, MalformedVectorsDecodeToNothing) {
    auto nan = MakeVector();
    nan.set_values(5, kNaN);
    auto short_values = MakeVector();
    short_values.mutable_values()->RemoveLast();
    auto round0 = MakeVector();
    round0.set_round(0);
    auto block = MakeVector();
    block.set_block_size(5);
    auto step = MakeVector();
    step.set_step(std::numeric_limits<std::uint32_t>::max());
    for (const auto& v : {nan, short_values, round0, block, step}) EXPECT_FALSE(FromProto(v));
}

TEST(ConvertCertificate, ReductionKeepsFiniteSumsOnly) {
    v1::CertificateReduction r;
    *r.mutable_header() = MakeHeader(1, 1, 0);
    r.set_round(9);
    r.set_step(2);
    r.set_stage(1);
    r.add_values(1.5);
    r.add_values(-2.0);
    const auto reduction = FromProto(r);
    ASSERT_TRUE(reduction.has_value());
    EXPECT_EQ(reduction->values, (std::vector<double>{1.5, -2.0}));
    EXPECT_EQ(reduction->stage, 1);
    r.add_values(std::numeric_limits<double>::infinity());
    EXPECT_FALSE(FromProto(r));
}

TEST(ConvertCertificate, RoundNeedsARankAndEachRobotOnce) {
    v1::CertificateRound round;
    round.set_round(5);
    round.set_rank_r(5);
    for (std::uint32_t robot : {0u, 1u}) round.add_bundles()->set_robot_id(robot);
    EXPECT_TRUE(IsValidRound(round));
    auto twice = round;
    twice.add_bundles()->set_robot_id(1);
    auto rank = round;
    rank.set_rank_r(1000);
    auto huge = round;
    huge.mutable_bundles(0)->add_neighbors(std::numeric_limits<std::uint32_t>::max());
    for (const auto& r : {twice, rank, huge}) EXPECT_FALSE(IsValidRound(r));
}

TEST(ConvertCertificate, StatusWithANonFiniteCostIsRefused) {
    v1::SolverStatus status;
    status.set_rank_r(5);
    status.set_cost(3.0);
    status.set_gradient_norm(0.1);
    EXPECT_TRUE(IsValidStatus(status));
    status.set_cost(kNaN);
    EXPECT_FALSE(IsValidStatus(status));
    status.set_cost(3.0);
    status.set_rank_r(100000);
    EXPECT_FALSE(IsValidStatus(status));
}

}  // namespace
}  // namespace certislam::actors
