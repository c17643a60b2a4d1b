// Distributed mode equals local mode: the same small simulated two-robot mission run by
// `certislam run` (one process, inproc) and by two `certislam robot` processes over tcp loopback
// with CURVE keys from `certislam keygen` gives the same trajectories within 1e-6, certified.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "tests/bin/shell.h"

namespace certislam {
namespace {

constexpr double kEqualTolerance = 1e-6;  ///< metres and quaternion components
constexpr int kKeyframes = 45;

std::string Binary() { return CERTISLAM_BINARY; }

std::vector<std::vector<double>> ReadTum(const std::string& path) {
    std::vector<std::vector<double>> rows;
    std::ifstream in(path);
    for (std::string line; std::getline(in, line);) {
        if (line.empty() || line[0] == '#') continue;
        std::istringstream fields(line);
        std::vector<double> row;
        for (double v; fields >> v;) row.push_back(v);
        rows.push_back(row);
    }
    return rows;
}

/// Largest difference of positions and (sign-aligned) quaternions of two TUM files.
double MaxDifference(const std::string& a_path, const std::string& b_path) {
    const auto a = ReadTum(a_path), b = ReadTum(b_path);
    if (a.size() != b.size() || a.empty()) return INFINITY;
    double worst = 0.0;
    for (size_t i = 0; i < a.size(); ++i) {
        if (a[i].size() != 8 || b[i].size() != 8) return INFINITY;
        double dot = 0.0;
        for (int k = 4; k < 8; ++k) dot += a[i][k] * b[i][k];
        const double sign = dot < 0 ? -1.0 : 1.0;
        for (int k = 1; k < 8; ++k) {
            worst = std::max(worst, std::abs(a[i][k] - (k >= 4 ? sign : 1.0) * b[i][k]));
        }
    }
    return worst;
}

class Distributed : public ::testing::Test {
  protected:
    void SetUp() override {
        dir_ = std::filesystem::temp_directory_path() /
               ("certislam_distributed_" + std::to_string(getpid()));
        std::filesystem::remove_all(dir_);
        std::filesystem::create_directories(dir_);
    }
    void TearDown() override { std::filesystem::remove_all(dir_); }

    std::string WriteConfig() {
        std::mt19937 rng(static_cast<unsigned>(getpid()));
        const int base = 30000 + static_cast<int>(rng() % 2000) * 10;
        std::ofstream out(dir_ / "team.json");
        out << R"({"robots": [0, 1],
  "source": {"kind": "simulator", "seed": 1, "max_keyframes": )"
            << kKeyframes << R"(},
  "solver": {"rank": 5, "rel_grad_tol": 1e-9},
  "matcher": {"query_stride": 3},
  "network": {
    "0": {"host": "127.0.0.1", "base_port": )"
            << base << R"(, "public_key": "robot0.pub", "secret_key": "robot0.key"},
    "1": {"host": "127.0.0.1", "base_port": )"
            << base + 10 << R"(, "public_key": "robot1.pub", "secret_key": "robot1.key"}}})";
        return (dir_ / "team.json").string();
    }

    std::filesystem::path dir_;
};

TEST_F(Distributed, TwoRobotProcessesOverTcpEqualTheSingleProcessRun) {
    for (int r = 0; r < 2; ++r) {
        const auto keygen = testing::Shell(Binary() + " keygen --out " +
                                           (dir_ / ("robot" + std::to_string(r))).string());
        ASSERT_EQ(keygen.exit_code, 0) << keygen.out;
    }
    const std::string config = WriteConfig();
    const auto local = testing::Shell(Binary() + " run " + config + " --json --timeout 120 --out " +
                                      (dir_ / "local").string() + " 2>&1");
    ASSERT_EQ(local.exit_code, 0) << local.out;
    EXPECT_NE(local.out.find("\"certified\": true"), std::string::npos) << local.out;

    // Robot 1 in the background, robot 0 in the foreground; both must finish certified.
    const std::string robot = Binary() + " robot " + config + " --json --timeout 120 --out " +
                              (dir_ / "distributed").string();
    const auto both = testing::Shell("(" + robot + " --id 1 > " + (dir_ / "r1.log").string() +
                                     " 2>&1; echo $? > " + (dir_ / "r1.rc").string() + ") & " +
                                     robot + " --id 0 2>&1; rc0=$?; wait; exit $rc0");
    ASSERT_EQ(both.exit_code, 0) << both.out;
    std::ifstream rc1(dir_ / "r1.rc");
    int code1 = -1;
    rc1 >> code1;
    std::ifstream log1(dir_ / "r1.log");
    const std::string out1((std::istreambuf_iterator<char>(log1)), {});
    ASSERT_EQ(code1, 0) << out1;
    EXPECT_NE(both.out.find("\"certified\": true"), std::string::npos) << both.out;
    EXPECT_NE(out1.find("\"certified\": true"), std::string::npos) << out1;

    for (int r = 0; r < 2; ++r) {
        const std::string name = "robot" + std::to_string(r) + ".tum";
        EXPECT_LT(
            MaxDifference((dir_ / "local" / name).string(), (dir_ / "distributed" / name).string()),
            kEqualTolerance)
            << name;
    }
}

TEST_F(Distributed, RobotKilledAndRestartedMidMissionRejoinsTheCertifiedOptimum) {
    for (int r = 0; r < 2; ++r) {
        ASSERT_EQ(testing::Shell(Binary() + " keygen --out " +
                                 (dir_ / ("robot" + std::to_string(r))).string())
                      .exit_code,
                  0);
    }
    const std::string config = WriteConfig();
    const auto local = testing::Shell(Binary() + " run " + config + " --json --timeout 120 --out " +
                                      (dir_ / "local").string() + " 2>&1");
    ASSERT_EQ(local.exit_code, 0) << local.out;
    const std::string robot = Binary() + " robot " + config + " --json --timeout 120 --out " +
                              (dir_ / "restarted").string() + " --log-dir " +
                              (dir_ / "logs").string();
    // Robot 1 is killed (SIGKILL) 1.5 s into the mission and started again 1 s later; it
    // replays its durable log (keyframes with clouds, accepted loops) before going on.
    const auto run = testing::Shell(
        "(" + robot + " --id 0 > " + (dir_ / "r0.log").string() + " 2>&1; echo $? > " +
        (dir_ / "r0.rc").string() + ") & " + robot + " --id 1 > /dev/null 2>&1 & victim=$!; " +
        "sleep 1.5; kill -9 $victim; sleep 1; " + robot + " --id 1 2>&1; rc1=$?; wait; exit $rc1");
    ASSERT_EQ(run.exit_code, 0) << run.out;
    std::ifstream rc0(dir_ / "r0.rc");
    int code0 = -1;
    rc0 >> code0;
    EXPECT_EQ(code0, 0);
    EXPECT_NE(run.out.find("\"certified\": true"), std::string::npos) << run.out;
    EXPECT_GT(std::filesystem::file_size(dir_ / "logs" / "robot1.keyframes.log"), 0u);
    for (int r = 0; r < 2; ++r) {
        const std::string name = "robot" + std::to_string(r) + ".tum";
        EXPECT_LT(
            MaxDifference((dir_ / "local" / name).string(), (dir_ / "restarted" / name).string()),
            kEqualTolerance)
            << name;
    }
}

TEST_F(Distributed, BadConfigurationFailsNamingTheField) {
    const std::pair<const char*, const char*> cases[] = {
        {R"({"kind": "sonar"})", "source.kind"},    // no such source
        {R"({"kind": "rosbag"})", "source.paths"},  // a bag per robot is required
    };
    for (const auto& [source, field] : cases) {
        std::ofstream(dir_ / "bad.json")
            << std::string(R"({"robots": [0, 1], "source": )") + source + "}";
        const auto result =
            testing::Shell(Binary() + " run " + (dir_ / "bad.json").string() + " 2>&1");
        EXPECT_EQ(result.exit_code, 1) << source;
        EXPECT_NE(result.out.find(field), std::string::npos) << result.out;
    }
}

}  // namespace
}  // namespace certislam
