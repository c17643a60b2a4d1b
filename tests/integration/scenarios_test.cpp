// `certislam demo --scenario NAME` end to end on the scenarios that show what the certificate is
// for: on tunnel-rendezvous (the default) and large-drift some local search stops in a local
// minimum the certificate refuses ("not optimal", lambda_min < 0) while certified RBCD from the
// same graph certifies and beats the baselines; every Table I row is on the actors' one graph.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "tests/integration/shell.h"

namespace certislam {
namespace {

// The paper's Table I improvements of certified RBCD, %, robot 0 and robot 1: the floors.
constexpr double kOverAlignmentPct[] = {48.9, 13.4};
constexpr double kOverOdometryPct[] = {48.4, 51.4};

nlohmann::json RunDemo(const std::string& args) {
    const auto run = testing::Shell(std::string(CERTISLAM_BINARY) + " demo " + args +
                                    " --voxel 0 --out '' --quiet --json");
    EXPECT_EQ(run.exit_code, 0) << run.out;
    return run.exit_code == 0 ? nlohmann::json::parse(run.out) : nlohmann::json::object();
}

/// A local-search row refused by its own certificate, certified RBCD certified.
void ExpectRefusalAndCertification(const nlohmann::json& j) {
    ASSERT_TRUE(j.contains("certified"));
    EXPECT_TRUE(j["certified"].get<bool>());
    EXPECT_EQ(j["verdict"].get<std::string>(), "certified");
    int refused = 0;
    for (const char* key : {"local_search", "local_search_from_alignment"}) {
        const auto& ls = j[key];
        if (ls["verdict"].get<std::string>() != "not optimal") continue;
        ++refused;
        EXPECT_FALSE(ls["certified"].get<bool>()) << key;
        EXPECT_LT(ls["lambda_min"].get<double>(), 0.0) << key;
        EXPECT_GT(ls["cost_minus_certified"].get<double>(), 0.0) << key;  // a worse critical point
    }
    EXPECT_GE(refused, 1) << j["local_search"].dump() << j["local_search_from_alignment"].dump();
    // One graph: the certified trajectory's cost on the team graph is the certified cost.
    EXPECT_NEAR(j["actor_graph"]["objective_of_trajectory_on_team_graph"].get<double>(),
                j["objective"].get<double>(), 1e-3 * j["objective"].get<double>());
}

TEST(Scenarios, DefaultIsTunnelRendezvousRefusesALocalMinimumAndBeatsThePaper) {
    const auto j = RunDemo("");
    ASSERT_TRUE(j.contains("scenario"));
    EXPECT_EQ(j["scenario"].get<std::string>(), "tunnel-rendezvous");
    ExpectRefusalAndCertification(j);
    ASSERT_EQ(j["robots"].size(), 2u);
    for (int r = 0; r < 2; ++r) {
        const auto& gain = j["robots"][r]["improvement_pct"];
        EXPECT_GT(gain["over_one_time_alignment"].get<double>(), kOverAlignmentPct[r]) << r;
        EXPECT_GT(gain["over_odometry"].get<double>(), kOverOdometryPct[r]) << r;
    }
}

TEST(Scenarios, LargeDriftRefusesALocalMinimum) {
    ExpectRefusalAndCertification(RunDemo("--scenario large-drift"));
}

TEST(Scenarios, CityCertifies) {
    const auto j = RunDemo("--scenario city");
    ASSERT_TRUE(j.contains("certified"));
    EXPECT_TRUE(j["certified"].get<bool>());
    EXPECT_EQ(j["scenario"].get<std::string>(), "city");
}

TEST(Scenarios, RejectsAnUnknownScenario) {
    const auto run = testing::Shell(std::string(CERTISLAM_BINARY) + " demo --scenario moon 2>&1");
    EXPECT_NE(run.exit_code, 0);
    EXPECT_NE(run.out.find("--scenario"), std::string::npos) << run.out;
}

}  // namespace
}  // namespace certislam
