// A two-robot pose-graph problem built by hand (overlapping circles, drifting odometry, robot 1
// in an unknown frame, noisy inter-robot loops), its centralised certified solution, and a
// feeder that plays the robots' ingest and loop matcher actors over real sockets.
#pragma once

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <memory>
#include <random>
#include <vector>

#include "actors/convert.h"
#include "actors/ingest_actor.h"
#include "actors/loop_matcher_actor.h"
#include "actors/solver_state.h"
#include "actors/wiring.h"
#include "certify/pipeline/mission.h"
#include "certislam/v1/control.pb.h"

namespace certislam::actors {

/// Odometry of two robots and the loops between them.
struct TwoRobotProblem {
    std::vector<std::vector<Eigen::Isometry3d>> odometry;  ///< [robot][keyframe]
    std::vector<slam::LoopClosure> loops;                  ///< inter-robot, a on robot 0
    SolverConfig config;                                   ///< solver settings (tight tolerance)
};

inline Eigen::Isometry3d Pose(double yaw, double x, double y, double z) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    T.translation() = Eigen::Vector3d(x, y, z);
    return T;
}

/// `n` keyframes per robot on a 25 m circle (robot 1 starts a quarter turn later), odometry
/// with small per-step noise, and `loops` inter-robot loops at truly coincident places.
inline TwoRobotProblem MakeTwoRobotProblem(int n, int loops, unsigned seed) {
    std::mt19937 rng(seed);
    std::normal_distribution<double> noise(0.0, 1.0);
    TwoRobotProblem p;
    p.config.rbcd.rel_grad_tol = 1e-9;
    const auto truth = [&](int robot, int i) {
        const double a = 2.0 * M_PI * (i + robot * n / 4.0) / n;
        return Pose(a + M_PI / 2, 25.0 * std::cos(a), 25.0 * std::sin(a), 0.1 * robot);
    };
    const auto perturb = [&](const Eigen::Isometry3d& T, double st, double sr) {
        Eigen::Isometry3d out = T;
        out.translation() += st * Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
        out.linear() =
            out.linear() *
            Eigen::AngleAxisd(sr * noise(rng), Eigen::Vector3d::UnitZ()).toRotationMatrix() *
            Eigen::AngleAxisd(sr * noise(rng), Eigen::Vector3d::UnitX()).toRotationMatrix();
        return out;
    };
    const Eigen::Isometry3d T_world_odom1 = Pose(1.3, -40.0, 12.0, 3.0);
    for (int r = 0; r < 2; ++r) {
        std::vector<Eigen::Isometry3d> odom{r == 0 ? truth(0, 0)
                                                   : T_world_odom1.inverse() * truth(1, 0)};
        for (int i = 1; i < n; ++i) {
            const Eigen::Isometry3d step = truth(r, i - 1).inverse() * truth(r, i);
            odom.push_back(odom.back() * perturb(step, 0.03, 0.002));
        }
        p.odometry.push_back(odom);
    }
    const certify::EdgeNoiseConfig& nc = p.config.noise;
    for (int k = 0; k < loops; ++k) {
        slam::LoopClosure l;
        const int j = (k * n / std::max(1, loops) + 3) % (n - n / 4);
        l.a = {0, j + n / 4};
        l.b = {1, j};
        l.T_a_b = perturb(truth(0, j + n / 4).inverse() * truth(1, j), 0.02, 0.001);
        l.kappa = 1.0 / (2.0 * nc.loop_sigma_r_rad * nc.loop_sigma_r_rad);
        l.tau = 1.0 / (nc.loop_sigma_t_m * nc.loop_sigma_t_m);
        p.loops.push_back(l);
    }
    return p;
}

/// Hands the problem to the robots' states (keyframes, then loops to both ends).
inline void FeedProblem(const TwoRobotProblem& p, std::vector<SolverState>& robots) {
    for (size_t r = 0; r < robots.size(); ++r) {
        for (size_t i = 0; i < p.odometry[r].size(); ++i) {
            robots[r].AddKeyframe(static_cast<int>(i), p.odometry[r][i]);
        }
    }
    for (auto& robot : robots) {
        for (const auto& l : p.loops) robot.AddLoop(l);
    }
}

/// The centralised certified solution, per robot, in robot 0's pose-0 frame.
inline std::vector<std::vector<Eigen::Isometry3d>> CentralSolution(const TwoRobotProblem& p) {
    const auto graph = certify::BuildJointGraph(p.odometry, p.loops, p.config.noise);
    certify::MissionSolverConfig solver;
    solver.rbcd.rel_grad_tol = 1e-10;
    const auto solution = certify::SolveCertifiedJoint(graph, solver);
    std::vector<std::vector<Eigen::Isometry3d>> out(p.odometry.size());
    for (int g = 0; g < graph.n; ++g) {
        Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
        T.matrix().topRows<3>() = solution.poses.block<3, 4>(0, 4 * g);
        out[graph.ids[g].robot].push_back(T);
    }
    return out;
}

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
        for (const auto& loop : p.loops) {
            auto proto = ToProto(loop);
            *proto.mutable_header() = MakeHeader(loop.b.robot, 1, 0);
            loops_[loop.b.robot]->Send(transport::Pack(proto));
        }
        for (size_t r = 0; r < loops_.size(); ++r) {
            loops_[r]->Send(End(static_cast<int>(r), kEndOfLoops));
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
