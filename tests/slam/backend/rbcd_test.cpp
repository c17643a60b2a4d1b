// RBCD reaches the published optima f* (data/g2o/README.md) on the small benchmark files, with one
// robot (centralised trust region) and with five (block coordinate descent).
#include "slam/backend/rbcd.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <string>

#include "slam/backend/chordal.h"
#include "slam/backend/connection_laplacian.h"
#include "slam/backend/rounding.h"
#include "slam/core/partition.h"
#include "slam/io/g2o_io.h"
#include "tests/data_paths.h"

namespace certislam::slam {
namespace {

constexpr double kRelGapTol = 1e-6;

struct Case {
    const char* file;
    double f_star;
    int robots;
    /// How far below the listed f* is accepted: SE-Sync's own estimate of parking-garage stops
    /// 1.3e-6 (1.06e-6 relative) above the certified optimum found here and by `certislam solve`.
    double below_tol = kRelGapTol;
};

std::string Name(const testing::TestParamInfo<Case>& info) {
    std::string s = info.param.file;
    s = s.substr(0, s.find('.'));
    std::replace(s.begin(), s.end(), '-', '_');  // gtest names: alphanumerics and '_' only
    return s + "_robots" + std::to_string(info.param.robots);
}

class RbcdReachesOptimum : public testing::TestWithParam<Case> {};

TEST_P(RbcdReachesOptimum, RoundedCostWithinRelativeGap) {
    const Case c = GetParam();
    const PoseGraphReadResult read = ReadG2o(test_data::G2oPath(c.file));
    ASSERT_TRUE(read.ok()) << read.error;
    const PoseGraph& graph = read.graph;
    const int rank = graph.d + 2;
    const Eigen::MatrixXd X0 = LiftToRank(ChordalInitialization(graph), rank);
    RbcdConfig config;
    const RbcdResult result = SolveRbcd(graph, ContiguousPartition(graph.n, c.robots), X0, config);
    // Converged, or stopped because the cost no longer decreases measurably (its rounding noise;
    // intel with one robot): both are judged by the gap to f* below.
    EXPECT_TRUE(result.status == RbcdResult::Status::kConverged ||
                result.status == RbcdResult::Status::kCostConverged ||
                result.status == RbcdResult::Status::kStalled)
        << static_cast<int>(result.status);
    const PoseMatrix poses = RoundSolution(graph, result.X);
    const double cost = Objective(graph, poses);
    const double gap = (cost - c.f_star) / c.f_star;
    std::printf(
        "%s robots %d: iterations %d, rtr %d, lifted %.10f, rounded %.10f, f* %.10f, "
        "gap %.2e, %.3f s\n",
        c.file, c.robots, result.iterations, result.rtr_iterations, result.cost, cost, c.f_star,
        gap, result.seconds);
    // One-sided: the reference optima are SE-Sync's rounded estimates, stopped at its own
    // tolerance; a certified estimate may be slightly below them (parking-garage is, by 1e-6).
    EXPECT_LE(gap, kRelGapTol);
    EXPECT_GE(gap, -c.below_tol);
}

// parking-garage is the ill-conditioned one (metric scale, f* = 1.26): it needs translations
// eliminated and, with 5 robots, the overlapping Schwarz finish to converge in reasonable time;
// it is the slowest case here (rank 5, no CG residual floor).
INSTANTIATE_TEST_SUITE_P(
    SmallFiles, RbcdReachesOptimum,
    testing::Values(Case{"tinyGrid3D.g2o", 18.5193868731, 1},
                    Case{"tinyGrid3D.g2o", 18.5193868731, 3},
                    Case{"smallGrid3D.g2o", 1025.39802075, 1},
                    Case{"smallGrid3D.g2o", 1025.39802075, 5}, Case{"CSAIL.g2o", 31.7037159922, 1},
                    Case{"CSAIL.g2o", 31.7037159922, 5}, Case{"MIT.g2o", 61.1541160916, 1},
                    Case{"MIT.g2o", 61.1541160916, 5}, Case{"intel.g2o", 52.3482275928, 1},
                    Case{"intel.g2o", 52.3482275928, 5},
                    Case{"parking-garage.g2o", 1.2624854718, 1, 2e-6},
                    Case{"parking-garage.g2o", 1.2624854718, 5, 2e-6}),
    Name);

}  // namespace
}  // namespace certislam::slam
