// PCM: exact maximum clique against brute force, the pairwise Mahalanobis test, and outlier
// rejection on a simulated two-robot mission with 30 % injected false loop closures.
#include "slam/frontend/pcm.h"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <numbers>
#include <random>
#include <set>

#include "slam/frontend/loop_detection.h"
#include "slam/sim/simulator.h"

namespace certislam::slam {
namespace {

constexpr double kFalseFraction = 0.3;       // of all candidates (issue 4)
constexpr double kMinTrueKept = 0.9;         // issue 4 floor
constexpr double kFalseMinTruthGapM = 20.0;  // a false loop joins places this far apart
constexpr double kLoopSigmaT = 0.05;         // noise of the true loops (registration-like)
constexpr double kLoopSigmaR = 0.002;

// Largest clique by enumerating all subsets (n <= 16).
size_t BruteForceClique(const std::vector<std::vector<int>>& adjacency) {
    const int n = static_cast<int>(adjacency.size());
    std::vector<std::set<int>> adj(n);
    for (int u = 0; u < n; ++u) adj[u].insert(adjacency[u].begin(), adjacency[u].end());
    size_t best = 0;
    for (std::uint32_t mask = 1; mask < (1u << n); ++mask) {
        const auto size = static_cast<size_t>(__builtin_popcount(mask));
        if (size <= best) continue;
        bool clique = true;
        for (int u = 0; u < n && clique; ++u) {
            for (int v = u + 1; v < n && clique; ++v) {
                if ((mask >> u & 1) && (mask >> v & 1) && !adj[u].count(v)) clique = false;
            }
        }
        if (clique) best = size;
    }
    return best;
}

TEST(MaximumClique, MatchesBruteForceOnRandomGraphs) {
    std::mt19937 rng(3);
    for (int trial = 0; trial < 40; ++trial) {
        const int n = 6 + trial % 10;
        const double p = 0.2 + 0.02 * trial;
        std::bernoulli_distribution edge(std::min(p, 0.9));
        std::vector<std::vector<int>> adjacency(n);
        for (int u = 0; u < n; ++u) {
            for (int v = u + 1; v < n; ++v) {
                if (edge(rng)) {
                    adjacency[u].push_back(v);
                    adjacency[v].push_back(u);
                }
            }
        }
        bool exact = false;
        std::int64_t nodes = 0;
        const auto clique = MaximumClique(adjacency, 1'000'000, &nodes, &exact);
        EXPECT_TRUE(exact);
        EXPECT_EQ(clique.size(), BruteForceClique(adjacency)) << "trial " << trial;
        for (size_t a = 0; a < clique.size(); ++a) {  // it is a clique
            for (size_t b = a + 1; b < clique.size(); ++b) {
                const auto& row = adjacency[clique[a]];
                EXPECT_NE(std::find(row.begin(), row.end(), clique[b]), row.end());
            }
        }
    }
}

TEST(MaximumClique, PlantedCliqueOfFortyInTwoHundredSparseVertices) {
    std::mt19937 rng(5);
    const int n = 200;
    std::bernoulli_distribution edge(0.1);
    std::vector<std::vector<int>> adjacency(n);
    auto link = [&](int u, int v) {
        adjacency[u].push_back(v);
        adjacency[v].push_back(u);
    };
    for (int u = 0; u < n; ++u) {
        for (int v = u + 1; v < n; ++v) {
            if ((u % 5 == 0 && v % 5 == 0) || edge(rng)) link(u, v);
        }
    }
    bool exact = false;
    const auto clique = MaximumClique(adjacency, 10'000'000, nullptr, &exact);
    EXPECT_TRUE(exact);
    ASSERT_EQ(clique.size(), 40u);
    for (const int u : clique) EXPECT_EQ(u % 5, 0);
}

TEST(MaximumClique, StartsFromASeedCliqueAndIgnoresOneThatIsNot) {
    // Vertices 0-4 form a 5-clique, 5-7 a triangle hanging off vertex 0.
    std::vector<std::vector<int>> adjacency(8);
    auto link = [&](int u, int v) {
        adjacency[u].push_back(v);
        adjacency[v].push_back(u);
    };
    for (int u = 0; u < 5; ++u) {
        for (int v = u + 1; v < 5; ++v) link(u, v);
    }
    link(5, 6), link(5, 7), link(6, 7), link(0, 5);
    bool exact = true;
    // A budget the first branch node exhausts: the answer is the seed, flagged inexact.
    const std::vector<int> triangle{5, 6, 7};
    EXPECT_EQ(MaximumClique(adjacency, 1, nullptr, &exact, triangle), triangle);
    EXPECT_FALSE(exact);
    // With budget, a seed does not stop the search from finding the larger clique.
    const std::vector<int> five{0, 1, 2, 3, 4};
    EXPECT_EQ(MaximumClique(adjacency, 1'000'000, nullptr, &exact, triangle), five);
    EXPECT_TRUE(exact);
    // Not a clique (6 and 1 are not adjacent; a repeated vertex; out of range): ignored.
    for (const std::vector<int>& bad :
         {std::vector<int>{6, 1}, std::vector<int>{2, 2}, std::vector<int>{0, 9}}) {
        EXPECT_TRUE(MaximumClique(adjacency, 1, nullptr, &exact, bad).empty());
    }
}

Information6 IsotropicInformation(double sigma_t, double sigma_r) {
    Information6 info = Information6::Zero();
    info.diagonal() << 1 / (sigma_t * sigma_t), 1 / (sigma_t * sigma_t), 1 / (sigma_t * sigma_t),
        1 / (sigma_r * sigma_r), 1 / (sigma_r * sigma_r), 1 / (sigma_r * sigma_r);
    return info;
}

TEST(Pcm, ConsistentPairIsSmallAndAShiftedOneIsLarge) {
    // Robot 0 and 1 drive straight along x; loop closures see each other 2 m to the left.
    std::vector<std::vector<Eigen::Isometry3d>> odometry(2);
    for (int k = 0; k < 20; ++k) {
        odometry[0].emplace_back(Eigen::Translation3d(3.0 * k, 0, 0));
        odometry[1].emplace_back(Eigen::Translation3d(3.0 * k, 0, 0));
    }
    const auto travelled = TravelledDistances(odometry);
    EXPECT_DOUBLE_EQ(travelled[0][19], 57.0);
    const Information6 info = IsotropicInformation(0.05, 0.002);
    const PcmMeasurement i{{0, 2}, {1, 2}, Eigen::Isometry3d(Eigen::Translation3d(0, 2, 0)), info};
    PcmMeasurement j{{0, 10}, {1, 10}, Eigen::Isometry3d(Eigen::Translation3d(0, 2, 0)), info};
    const PcmConfig config;
    EXPECT_LT(PairwiseMahalanobis2(i, j, odometry, travelled, config), 1e-9);
    j.T_a_b = Eigen::Isometry3d(Eigen::Translation3d(8, 2, 0));  // 8 m off after 24 m
    EXPECT_GT(PairwiseMahalanobis2(i, j, odometry, travelled, config), config.chi2_threshold);
}

TEST(Pcm, ConfigValidationNamesTheField) {
    PcmConfig config;
    config.chi2_threshold = -1;
    try {
        config.Validate();
        FAIL() << "no throw";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("chi2_threshold"), std::string::npos);
    }
}

// A false loop: two keyframes far apart in truth with a plausible-looking wrong measurement (what
// a wrong Scan Context match plus registration gives: a few metres, any yaw).
PcmMeasurement FalseLoop(std::mt19937_64& rng, const MissionGenerator& g) {
    std::uniform_int_distribution<int> robot(0, g.num_robots() - 1);
    std::uniform_real_distribution<double> yaw(-std::numbers::pi, std::numbers::pi), xy(-5, 5);
    for (;;) {
        const int ra = robot(rng), rb = robot(rng);
        std::uniform_int_distribution<int> ka(0, g.num_keyframes(ra) - 1),
            kb(0, g.num_keyframes(rb) - 1);
        const PoseId a{ra, ka(rng)}, b{rb, kb(rng)};
        if (a == b) continue;
        const double gap = (g.T_world_sensor_truth(ra, a.index).translation() -
                            g.T_world_sensor_truth(rb, b.index).translation())
                               .norm();
        if (gap < kFalseMinTruthGapM) continue;
        Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
        T.linear() = Eigen::AngleAxisd(yaw(rng), Eigen::Vector3d::UnitZ()).toRotationMatrix();
        T.translation() << xy(rng), xy(rng), 0.0;
        return {a, b, T, IsotropicInformation(2 * kLoopSigmaT, 5 * kLoopSigmaR)};
    }
}

TEST(Pcm, RejectsEveryInjectedFalseLoopAndKeepsNinetyPercentOfTrueOnes) {
    const MissionGenerator g(SimulatorConfig{});
    std::vector<std::vector<Eigen::Isometry3d>> odometry(g.num_robots()), truth(g.num_robots());
    for (int r = 0; r < g.num_robots(); ++r) {
        for (int k = 0; k < g.num_keyframes(r); ++k) {
            odometry[r].push_back(g.PoseOnly(r, k).T_odom_sensor);
            truth[r].push_back(g.T_world_sensor_truth(r, k));
        }
    }
    LoopDetectionConfig gt;
    gt.gt_noise_t_m = kLoopSigmaT;
    gt.gt_noise_r_rad = kLoopSigmaR;
    const auto true_loops = GroundTruthLoops(truth, gt);
    ASSERT_GE(true_loops.size(), 30u);
    for (std::uint64_t seed = 11; seed < 41; ++seed) {  // thirty injections
        std::vector<PcmMeasurement> measurements;
        std::vector<bool> is_true;
        for (const auto& l : true_loops) {
            measurements.push_back(
                {l.a, l.b, l.T_a_b, IsotropicInformation(2 * kLoopSigmaT, 5 * kLoopSigmaR)});
            is_true.push_back(true);
        }
        std::mt19937_64 rng(seed);
        const auto num_false = static_cast<size_t>(std::ceil(
            kFalseFraction / (1 - kFalseFraction) * static_cast<double>(true_loops.size())));
        std::uniform_int_distribution<size_t> slot(0, measurements.size());
        for (size_t f = 0; f < num_false; ++f) {
            const auto at = static_cast<long>(slot(rng) % (measurements.size() + 1));
            measurements.insert(measurements.begin() + at, FalseLoop(rng, g));
            is_true.insert(is_true.begin() + at, false);
        }
        const PcmResult result = RejectOutliersPcm(measurements, odometry, PcmConfig{});
        EXPECT_EQ(result.status, PcmResult::Status::kExact);
        int true_kept = 0, false_kept = 0, num_true = 0;
        for (size_t k = 0; k < measurements.size(); ++k) {
            num_true += is_true[k];
            if (result.inlier[k]) (is_true[k] ? true_kept : false_kept) += 1;
        }
        for (size_t k = 0; k < measurements.size(); ++k) {
            if (!is_true[k] && result.inlier[k]) {
                const auto& m = measurements[k];
                std::cout << "FALSE kept " << m.a.robot << ":" << m.a.index << " " << m.b.robot
                          << ":" << m.b.index << " truth "
                          << (truth[m.a.robot][m.a.index].inverse() * truth[m.b.robot][m.b.index])
                                 .translation()
                                 .transpose()
                          << " meas " << m.T_a_b.translation().transpose() << "\n";
            }
        }
        EXPECT_EQ(false_kept, 0);
        EXPECT_GE(true_kept, kMinTrueKept * num_true)
            << true_kept << " of " << num_true << " true loops kept; groups " << result.groups
            << ", consistent pairs " << result.consistent_pairs << ", odometry-rejected "
            << result.rejected_by_odometry;
        std::cout << "true loops " << num_true << " kept " << true_kept << "; false " << num_false
                  << " kept " << false_kept << "; branch nodes " << result.branch_nodes << "\n";
    }
}

}  // namespace
}  // namespace certislam::slam
