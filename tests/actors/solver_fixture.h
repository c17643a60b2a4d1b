// The two-robot problem (tests/certify/pipeline/two_robot_problem.h) and a feeder that plays
// the robots' ingest and loop matcher actors over real sockets.
#pragma once

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <memory>
#include <set>
#include <utility>
#include <vector>

#include "actors/convert.h"
#include "actors/ingest_actor.h"
#include "actors/loop_matcher_actor.h"
#include "actors/wiring.h"
#include "certislam/v1/control.pb.h"
#include "tests/certify/pipeline/two_robot_problem.h"

namespace certislam::actors {

using certify::CentralSolution;
using certify::FeedProblem;
using certify::MakeTwoRobotProblem;
using certify::TwoRobotProblem;
using slam::testing::Pose;

/// Plays ingest and loop matcher for the given robots: keyframes (empty clouds), loops, ends.
class Feeder {
  public:
    Feeder(zmq::context_t& context, const std::vector<int>& robots, int solvers) {
        for (int r : robots) {
            const TeamWiring w = InprocWiring(r, robots);
            keyframes_.push_back(
                std::make_unique<transport::Endpoint>(context, ServerConfig(w, Edge::kKeyframes)));
            loops_.push_back(
                std::make_unique<transport::Endpoint>(context, ServerConfig(w, Edge::kLoops)));
        }
        for (auto& e : keyframes_) EXPECT_TRUE(e->WaitForSubscribers(1, std::chrono::seconds(5)));
        for (auto& e : loops_) {
            EXPECT_TRUE(e->WaitForSubscribers(solvers, std::chrono::seconds(5)));
        }
    }
    void Feed(const TwoRobotProblem& p) {
        FeedKeyframes(p);
        FeedLoops(p);
        FeedLoopEnds(p, false);
    }
    /// Every robot's keyframes (empty clouds) and its end of keyframes.
    void FeedKeyframes(const TwoRobotProblem& p) {
        for (size_t r = 0; r < p.odometry.size(); ++r) {
            for (size_t i = 0; i < p.odometry[r].size(); ++i) {
                slam::Keyframe kf;
                kf.robot = static_cast<int>(r);
                kf.index = static_cast<int>(i);
                kf.stamp_ns = static_cast<std::int64_t>(i) * 100000000;
                kf.T_odom_sensor = p.odometry[r][i];
                kf.cloud = std::make_shared<slam::PointCloud>();
                keyframes_[r]->Send(EncodeKeyframe(kf, i + 1));
            }
            keyframes_[r]->Send(End(static_cast<int>(r), kEndOfKeyframes));
        }
    }
    /// Every loop, on the loop stream of its head's robot.
    void FeedLoops(const TwoRobotProblem& p) {
        for (const auto& loop : p.loops) {
            auto proto = ToProto(loop);
            *proto.mutable_header() = MakeHeader(loop.b.robot, 1, 0);
            loops_[loop.b.robot]->Send(transport::Pack(proto));
        }
    }
    /// Every robot's end of loops; `counted`: with the number of loops its stream carries.
    void FeedLoopEnds(const TwoRobotProblem& p, bool counted) {
        for (size_t r = 0; r < loops_.size(); ++r) {
            auto end = End(static_cast<int>(r), kEndOfLoops);
            if (counted) {  // distinct ends, as a pose-graph source counts them
                std::set<std::pair<slam::PoseId, slam::PoseId>> ends;
                for (const auto& l : p.loops) {
                    if (l.b.robot == int(r)) ends.insert({l.a, l.b});
                }
                v1::Shutdown proto = *transport::Unpack<v1::Shutdown>(end);
                proto.set_count(ends.size());
                end = transport::Pack(proto);
            }
            loops_[r]->Send(end);
        }
    }

  private:
    static transport::Message End(int robot, const char* reason) {
        v1::Shutdown end;
        *end.mutable_header() = MakeHeader(robot, 1, 0);
        end.set_reason(reason);
        return transport::Pack(end);
    }
    std::vector<std::unique_ptr<transport::Endpoint>> keyframes_, loops_;
};

}  // namespace certislam::actors
