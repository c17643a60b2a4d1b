// Runs the real `certislam eval` on trajectory files in a temp dir and parses its JSON.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "tests/integration/shell.h"
#include "tests/scratch_dir.h"

namespace {

constexpr double kExact = 1e-6;  ///< JSON doubles of exact figures

using certislam::testing::Shell;
using certislam::testing::ShellResult;

std::filesystem::path TempDir() {
    const auto dir = certislam::testing::ScratchDir();
    std::filesystem::create_directories(dir);
    return dir;
}

/// Writes a TUM circle of n poses, moved by (dx, dy, dz) and yawed by `yaw` about the origin.
std::string WriteCircle(const std::string& name, int n, double dx, double dz, double yaw) {
    const auto path = (TempDir() / name).string();
    std::ofstream out(path);
    out.precision(17);
    out << "# stamp x y z qx qy qz qw\n";
    for (int k = 0; k < n; ++k) {
        const double a = 2 * M_PI * k / n;
        const double x = 10 * std::cos(a), y = 10 * std::sin(a), z = 0.1 * k;
        const double xr = std::cos(yaw) * x - std::sin(yaw) * y + dx;
        const double yr = std::sin(yaw) * x + std::cos(yaw) * y;
        const double h = 0.5 * (a + yaw);
        out << k * 0.1 << " " << xr << " " << yr << " " << z + dz << " 0 0 " << std::sin(h) << " "
            << std::cos(h) << "\n";
    }
    return path;
}

std::string Eval(const std::string& args) {
    return std::string(CERTISLAM_BINARY) + " eval " + args + " 2>&1";
}

TEST(EvalCommand, RigidlyMovedEstimateHasZeroAteAfterAlignmentAndItsOffsetWithout) {
    const auto gt = WriteCircle("gt.tum", 60, 0, 0, 0);
    const auto est = WriteCircle("est.tum", 60, 3, 4, 0);  // moved by 5 m
    const ShellResult aligned = Shell(Eval("--gt " + gt + " --est " + est + " --json"));
    ASSERT_EQ(aligned.exit_code, 0) << aligned.out;
    const auto j = nlohmann::json::parse(aligned.out);
    EXPECT_NEAR(j["ate_rmse"].get<double>(), 0.0, kExact);
    EXPECT_NEAR(j["rpe_rmse"].get<double>(), 0.0, kExact);
    EXPECT_EQ(j["pairs"].get<int>(), 60);
    const ShellResult raw = Shell(Eval("--gt " + gt + " --est " + est + " --align none --json"));
    ASSERT_EQ(raw.exit_code, 0) << raw.out;
    EXPECT_NEAR(nlohmann::json::parse(raw.out)["ate_rmse"].get<double>(), 5.0, kExact);
}

TEST(EvalCommand, JointAlignmentOfTwoRobotsKeepsTheirRelativeOffset) {
    const auto gt0 = WriteCircle("gt0.tum", 40, 0, 0, 0);
    const auto gt1 = WriteCircle("gt1.tum", 40, 0, 0, 1.0);
    const auto est1 = WriteCircle("est1.tum", 40, 0, 2.0, 1.0);  // robot 1 off by 2 m in z
    const ShellResult run = Shell(
        Eval("--gt " + gt0 + " --est " + gt0 + " --gt " + gt1 + " --est " + est1 + " --json"));
    ASSERT_EQ(run.exit_code, 0) << run.out;
    const auto j = nlohmann::json::parse(run.out);
    ASSERT_EQ(j["robots"].size(), 2u);
    EXPECT_NEAR(j["robots"][1]["ate_rmse_own_alignment"].get<double>(), 0.0, kExact);
    // A z shift of -1 m leaves +-1 m on each robot, so the joint optimum is at most 1 m; no
    // rigid motion can remove a 2 m offset between two robots on the same circle.
    EXPECT_LE(j["ate_rmse"].get<double>(), 1.0 + kExact);
    EXPECT_GT(j["ate_rmse"].get<double>(), 0.5);
}

/// Writes a KITTI file of n poses on a line along x.
std::string WriteKittiLine(const std::string& name, int n) {
    const auto path = (TempDir() / name).string();
    std::ofstream out(path);
    for (int k = 0; k < n; ++k) out << "1 0 0 " << k << " 0 1 0 0 0 0 1 0\n";
    return path;
}

TEST(EvalCommand, KittiFilesOfDifferentLengthsAreRefusedUnlessAsked) {
    const auto gt = WriteKittiLine("gt.kitti", 100);
    const auto est = WriteKittiLine("est.kitti", 40);
    const std::string args = "--format kitti --gt " + gt + " --est " + est + " --json";
    const ShellResult refused = Shell(Eval(args));
    EXPECT_EQ(refused.exit_code, 1) << refused.out;
    EXPECT_NE(refused.out.find(gt + " has 100 poses but " + est + " has 40"), std::string::npos)
        << refused.out;
    const ShellResult allowed = Shell(Eval(args + " --allow-length-mismatch"));
    ASSERT_EQ(allowed.exit_code, 0) << allowed.out;
    const auto j = nlohmann::json::parse(allowed.out);
    EXPECT_EQ(j["pairs"].get<int>(), 40);
    EXPECT_EQ(j["schema_version"].get<int>(), 1);
}

TEST(EvalCommand, AllEqualStampsAreRefusedUnlessAsked) {
    const auto gt = WriteCircle("gt_stamps.tum", 30, 0, 0, 0);
    const auto est = (TempDir() / "est_same_stamp.tum").string();
    {
        std::ifstream in(WriteCircle("est_src.tum", 30, 1, 0, 0));
        std::ofstream out(est);
        std::string line;
        while (std::getline(in, line)) {
            if (line[0] == '#') continue;
            out << "0.0" << line.substr(line.find(' ')) << "\n";  // every stamp 0
        }
    }
    const ShellResult refused = Shell(Eval("--gt " + gt + " --est " + est));
    EXPECT_EQ(refused.exit_code, 1) << refused.out;
    EXPECT_NE(refused.out.find(est + ": every stamp is equal"), std::string::npos) << refused.out;
    const ShellResult allowed =
        Shell(Eval("--gt " + gt + " --est " + est + " --allow-equal-stamps"));
    EXPECT_EQ(allowed.out.find("every stamp is equal"), std::string::npos) << allowed.out;
}

TEST(EvalCommand, BadFileGivesFileAndLineAndNonZeroExit) {
    const auto gt = WriteCircle("gt_ok.tum", 10, 0, 0, 0);
    const auto bad = (TempDir() / "bad.tum").string();
    std::ofstream(bad) << "0 0 0 0 0 0 0 1\n0.1 0 0 zero 0 0 0 1\n";
    const ShellResult run = Shell(Eval("--gt " + gt + " --est " + bad));
    EXPECT_NE(run.exit_code, 0);
    EXPECT_NE(run.out.find(bad + ":2: not a number: 'zero'"), std::string::npos) << run.out;
}

}  // namespace
