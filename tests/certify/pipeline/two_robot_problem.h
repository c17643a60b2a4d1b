// A two-robot pose-graph problem built by hand (overlapping circles, drifting odometry, robot 1
// in an unknown frame, noisy inter-robot loops), fed to robots' solver states, and its
// centralised certified solution.
#pragma once

#include <Eigen/Geometry>
#include <utility>
#include <vector>

#include "certify/pipeline/mission.h"
#include "certify/pipeline/solver_state.h"
#include "tests/slam/frontend/two_robot_circles.h"

namespace certislam::certify {

/// Odometry of two robots and the loops between them.
struct TwoRobotProblem {
    std::vector<std::vector<Eigen::Isometry3d>> odometry;  ///< [robot][keyframe]
    std::vector<slam::LoopClosure> loops;                  ///< inter-robot, a on robot 0
    SolverConfig config;                                   ///< solver settings (tight tolerance)
};

/// The two-robot circles (tests/slam/frontend/two_robot_circles.h) with loops weighted by the
/// solver's noise model.
inline TwoRobotProblem MakeTwoRobotProblem(int n, int loops, unsigned seed) {
    TwoRobotProblem p;
    p.config.rbcd.rel_grad_tol = 1e-9;
    const EdgeNoiseConfig& nc = p.config.noise;
    slam::testing::TwoRobotCircles circles = slam::testing::MakeTwoRobotCircles(
        n, loops, seed, 1.0 / (2.0 * nc.loop_sigma_r_rad * nc.loop_sigma_r_rad),
        1.0 / (nc.loop_sigma_t_m * nc.loop_sigma_t_m));
    p.odometry = std::move(circles.odometry);
    p.loops = std::move(circles.loops);
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
    const auto graph = BuildJointGraph(p.odometry, p.loops, p.config.noise);
    MissionSolverConfig solver;
    solver.rbcd.rel_grad_tol = 1e-10;
    const auto solution = SolveCertifiedJoint(graph, solver);
    std::vector<std::vector<Eigen::Isometry3d>> out(p.odometry.size());
    for (int g = 0; g < graph.n; ++g) {
        Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
        T.matrix().topRows<3>() = solution.poses.block<3, 4>(0, 4 * g);
        out[graph.ids[g].robot].push_back(T);
    }
    return out;
}

}  // namespace certislam::certify
