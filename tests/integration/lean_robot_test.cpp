// `certislam-robot`, the back-end-only robot executable: `solve --distributed` over tcp and ipc
// starts it for every robot and certifies the in-process optimum; it takes `certislam robot`'s
// configuration and gives its errors; a keyframe source is refused naming source.kind.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "tests/data_paths.h"
#include "tests/integration/shell.h"
#include "tests/scratch_dir.h"

namespace {

using certislam::testing::Shell;
using certislam::testing::ShellResult;
using certislam::testing::WriteScratch;

/// Distributed vs in-process cost (as in solve_distributed_test.cpp).
constexpr double kRelCost = 1e-6;

using certislam::test_data::G2oPath;

nlohmann::json Json(const std::string& args) {
    const ShellResult r = Shell(std::string(CERTISLAM_BINARY) + " " + args + " --json 2>&1");
    EXPECT_EQ(r.exit_code, 0) << args << "\n" << r.out;
    return nlohmann::json::parse(r.out, nullptr, false);
}

double RelDiff(double a, double b) { return std::abs(a - b) / std::abs(b); }

TEST(LeanRobot, SolveDistributedRunsItPerRobotAndCertifiesTheInProcessOptimum) {
    const auto central = Json("solve " + G2oPath("smallGrid3D.g2o") + " --robots 1 --quiet");
    for (const std::string transport : {"tcp", "ipc"}) {
        const auto team = Json("solve " + G2oPath("smallGrid3D.g2o") +
                               " --robots 3 --distributed --timeout 120 --transport " + transport);
        ASSERT_FALSE(team.is_discarded()) << transport;
        EXPECT_EQ(team["robot_executable"], "certislam-robot") << transport;
        EXPECT_EQ(team["verdict"], "certified") << transport;
        EXPECT_LE(RelDiff(team["cost"].get<double>(), central["cost"].get<double>()), kRelCost)
            << transport;
        ASSERT_EQ(team["peak_rss_mb_by_robot"].size(), 3u) << transport;
    }
}

TEST(LeanRobot, TwoProcessesOverTcpCertifyAndWriteTheirReports) {
    const auto central = Json("solve " + G2oPath("smallGrid3D.g2o") + " --quiet");
    const auto out = certislam::testing::ScratchDir() / "out";
    std::filesystem::create_directories(out);
    const std::string config = WriteScratch("tcp.yaml",
                                            "robots: [0, 1]\nsource:\n  kind: pose_graph\n"
                                            "  graph: " +
                                                G2oPath("smallGrid3D.g2o") +
                                                "\nnetwork:\n"
                                                "  0: {host: 127.0.0.1, base_port: 17910}\n"
                                                "  1: {host: 127.0.0.1, base_port: 17920}\n");
    const std::string robot =
        std::string(CERTISLAM_ROBOT_BINARY) + " " + config + " --timeout 120 --out " + out.string();
    const ShellResult r =
        Shell(robot + " --id 1 > /dev/null 2>&1 & " + robot + " --id 0 > /dev/null 2>&1; wait");
    for (const int id : {0, 1}) {
        std::ifstream in(out / ("robot" + std::to_string(id) + ".report.json"));
        const auto j = nlohmann::json::parse(in, nullptr, false);
        ASSERT_FALSE(j.is_discarded()) << id << r.out;
        EXPECT_EQ(j["robot"], id);
        EXPECT_EQ(j["verdict"], "certified");
        EXPECT_LE(RelDiff(j["cost"].get<double>(), central["cost"].get<double>()), kRelCost);
    }
}

TEST(LeanRobot, GivesTheRobotCommandsErrorsAndRefusesKeyframeSources) {
    const std::string long_dir(120, 'x');
    const std::string bad_ipc =
        WriteScratch("ipc.yaml",
                     "robots: [0, 1]\nsource:\n  kind: pose_graph\n"
                     "  graph: " +
                         G2oPath("tinyGrid3D.g2o") + "\nnetwork:\n  0: {ipc_dir: /tmp/" + long_dir +
                         "}\n  1: {ipc_dir: /tmp}\n");
    const ShellResult lean =
        Shell(std::string(CERTISLAM_ROBOT_BINARY) + " " + bad_ipc + " --id 1 --timeout 5 2>&1");
    const ShellResult full =
        Shell(std::string(CERTISLAM_BINARY) + " robot " + bad_ipc + " --id 1 --timeout 5 2>&1");
    EXPECT_EQ(lean.exit_code, 1) << lean.out;
    EXPECT_EQ(full.exit_code, 1) << full.out;
    EXPECT_EQ(lean.out.substr(lean.out.find(": ")), full.out.substr(full.out.find(": ")));
    EXPECT_NE(lean.out.find("certislam-robot: "), std::string::npos) << lean.out;

    const std::string keyframes =
        WriteScratch("sim.yaml",
                     "robots: [0, 1]\nsource: {kind: simulator}\nnetwork:\n"
                     "  0: {host: 127.0.0.1, base_port: 17930}\n  1: {host: 127.0.0.1, "
                     "base_port: 17940}\n");
    const ShellResult refused =
        Shell(std::string(CERTISLAM_ROBOT_BINARY) + " " + keyframes + " --id 0 2>&1");
    EXPECT_EQ(refused.exit_code, 1) << refused.out;
    EXPECT_NE(refused.out.find("source.kind"), std::string::npos) << refused.out;
    const ShellResult usage = Shell(std::string(CERTISLAM_ROBOT_BINARY) + " 2>&1");
    EXPECT_EQ(usage.exit_code, 2) << usage.out;
}

}  // namespace
