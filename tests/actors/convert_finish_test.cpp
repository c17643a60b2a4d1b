// The team finish's messages on the wire: what a robot's TeamFinish sends decodes to what it
// held (a failing robot's non-finite sums included, which end the team's finish together);
// an unknown kind, a vector whose value count does not match its ids and rank, a rank beyond 64,
// a bad pose id or edge, or ids beyond an int decode to nothing.
#include <gtest/gtest.h>

#include <limits>

#include "actors/convert.h"

namespace certislam::actors {
namespace {

v1::FinishMessage Stamped(v1::FinishMessage m, int robot) {
    *m.mutable_header() = MakeHeader(robot, 1, 0);
    m.set_staircase_level(2);
    return m;
}

certify::FinishVector MakeVector() {
    certify::FinishVector v;
    v.to = 3;
    v.step = 41;
    v.ids = {{1, 0}, {3, 7}};
    v.blocks = Eigen::MatrixXd::Random(5, 8);
    return v;
}

TEST(ConvertFinish, VectorEdgesAndSumsDecodeToWhatWasSent) {
    const certify::FinishVector vector = MakeVector();
    const auto v = FromProto(Stamped(ToProto(vector), 1));
    ASSERT_TRUE(v.has_value());
    EXPECT_EQ(v->kind, v1::FinishMessage::KIND_VECTOR);
    EXPECT_EQ(v->robot, 1);
    EXPECT_EQ(v->to, 3);
    EXPECT_EQ(v->step, 41u);
    EXPECT_EQ(v->staircase_level, 2);
    EXPECT_EQ(v->ids, vector.ids);
    EXPECT_EQ(v->blocks, vector.blocks);

    certify::FinishEdges edges;
    edges.to = 2;
    edges.poses = {{1, 4}};
    slam::LoopClosure loop;
    loop.a = {1, 4};
    loop.b = {2, 0};
    loop.T_a_b.translation() << 1.0, 2.0, 3.0;
    loop.kappa = 5.0;
    loop.tau = 7.0;
    edges.edges = {loop};
    const auto e = FromProto(Stamped(ToProto(edges), 1));
    ASSERT_TRUE(e.has_value());
    EXPECT_EQ(e->kind, v1::FinishMessage::KIND_EDGES);
    EXPECT_EQ(e->to, 2);
    EXPECT_EQ(e->ids, edges.poses);
    ASSERT_EQ(e->edges.size(), 1u);
    EXPECT_EQ(e->edges[0].b, loop.b);
    EXPECT_TRUE(e->edges[0].T_a_b.isApprox(loop.T_a_b));

    // A failing robot's share is NaN: it must reach the team as it is.
    const certify::FinishSums sums{9, {1.5, std::numeric_limits<double>::quiet_NaN()}};
    const auto s = FromProto(Stamped(ToProto(sums), 4));
    ASSERT_TRUE(s.has_value());
    EXPECT_EQ(s->kind, v1::FinishMessage::KIND_SUMS);
    EXPECT_EQ(s->step, 9u);
    ASSERT_EQ(s->values.size(), 2u);
    EXPECT_EQ(s->values[0], 1.5);
    EXPECT_TRUE(std::isnan(s->values[1]));

    // The scatter a failing robot still owes: no ids, no values, of its rank.
    certify::FinishVector empty;
    empty.to = 2;
    empty.blocks = Eigen::MatrixXd(5, 0);
    const auto none = FromProto(Stamped(ToProto(empty), 1));
    ASSERT_TRUE(none.has_value());
    EXPECT_TRUE(none->ids.empty());
    EXPECT_EQ(none->blocks.rows(), 5);
    EXPECT_EQ(none->blocks.cols(), 0);
}

TEST(ConvertFinish, MalformedMessagesDecodeToNothing) {
    const v1::FinishMessage good = Stamped(ToProto(MakeVector()), 1);
    ASSERT_TRUE(FromProto(good));
    auto short_values = good;
    short_values.mutable_values()->RemoveLast();
    auto rank0 = good;
    rank0.set_rank_r(0);
    auto rank65 = good;
    rank65.set_rank_r(65);
    auto kind = good;
    kind.set_kind(v1::FinishMessage::KIND_UNSPECIFIED);
    auto robot = good;
    robot.mutable_header()->set_robot_id(std::numeric_limits<std::uint32_t>::max());
    auto to = good;
    to.set_to_robot(std::numeric_limits<std::uint32_t>::max());
    auto id = good;
    id.mutable_pose_ids(0)->set_index(std::numeric_limits<std::uint64_t>::max());
    certify::FinishEdges edges;
    edges.to = 2;
    auto bad_edge = Stamped(ToProto(edges), 1);
    bad_edge.add_edges();  // no ids, no weights
    for (const auto& m : {short_values, rank0, rank65, kind, robot, to, id, bad_edge}) {
        EXPECT_FALSE(FromProto(m)) << m.ShortDebugString().substr(0, 120);
    }
}

}  // namespace
}  // namespace certislam::actors
