// `certislam demo` end to end: the real binary on the city two-robot mission (the
// claim of Table I; a shorter mission has too few rendezvous to show it) writes every file (TUM
// trajectories, g2o, PLY, report.json, SVG), the JSON has the issue's keys, and certified RBCD
// from the actor graph beats odometry and the one-time alignment for every robot, certified;
// --keyframes truncates (checked on the --pipeline path, the quick one).
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "tests/integration/shell.h"

namespace certislam {
namespace {

constexpr int kShortKeyframes = 60;  ///< per robot, for the --keyframes check
constexpr int kRobots = 2;

std::string ReadFile(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

int CountLines(const std::string& text, const std::string& prefix) {
    int n = 0;
    std::istringstream in(text);
    for (std::string line; std::getline(in, line);) n += line.rfind(prefix, 0) == 0 ? 1 : 0;
    return n;
}

class Demo : public ::testing::Test {
  protected:
    static void SetUpTestSuite() {
        dir_ = new std::filesystem::path(std::filesystem::temp_directory_path() /
                                         ("certislam_demo_" + std::to_string(getpid())));
        std::filesystem::remove_all(*dir_);
        run_ = new testing::ShellResult(testing::Shell(
            std::string(CERTISLAM_BINARY) + " demo --scenario city --robots " +
            std::to_string(kRobots) + " --voxel 1.0 --actors-timeout 240 --quiet --json --out " +
            dir_->string()));
    }
    static void TearDownTestSuite() {
        std::filesystem::remove_all(*dir_);
        delete run_;
        delete dir_;
    }
    static std::filesystem::path* dir_;
    static testing::ShellResult* run_;
};
std::filesystem::path* Demo::dir_ = nullptr;
testing::ShellResult* Demo::run_ = nullptr;

TEST_F(Demo, ExitsZeroAndPrintsTheReportAsJson) {
    ASSERT_EQ(run_->exit_code, 0) << run_->out;
    const auto printed = nlohmann::json::parse(run_->out);
    const auto written = nlohmann::json::parse(ReadFile(*dir_ / "report.json"));
    EXPECT_EQ(printed["robots"], written["robots"]);
    EXPECT_EQ(printed["lambda_min"], written["lambda_min"]);
}

TEST_F(Demo, ReportHasTheIssueKeysAndCertifiedBeatsTheBaselines) {
    ASSERT_EQ(run_->exit_code, 0) << run_->out;
    const auto j = nlohmann::json::parse(ReadFile(*dir_ / "report.json"));
    for (const char* key :
         {"robots", "certified", "lambda_min", "inter_robot_loops", "bytes_sent", "seconds"}) {
        EXPECT_TRUE(j.contains(key)) << key;
    }
    EXPECT_TRUE(j["certified"].get<bool>());
    // One certified objective with the bound the certificate proved for it.
    EXPECT_EQ(j["verdict"].get<std::string>(), "certified");
    EXPECT_EQ(j["schema_version"].get<int>(), 1);
    ASSERT_TRUE(j.contains("lower_bound")) << "certified without a proven bound";
    EXPECT_LE(j["lower_bound"].get<double>(), j["objective"].get<double>());
    EXPECT_LE(j["relative_suboptimality_bound"].get<double>(), 1e-6);
    // The certified row, the certificate, the loops and the bytes come from the actor graph.
    EXPECT_EQ(j["certified_source"].get<std::string>(), "actor graph");
    EXPECT_TRUE(j["actor_graph"]["done"].get<bool>());
    EXPECT_GT(j["actor_graph"]["map_submaps"].get<int>(), kRobots);  // every robot's submaps
    EXPECT_GT(j["inter_robot_loops"].get<int>(), 0);
    EXPECT_GT(j["bytes_sent"].get<std::int64_t>(), 0);
    EXPECT_GT(j["seconds"].get<double>(), 0.0);
    ASSERT_EQ(j["robots"].size(), static_cast<size_t>(kRobots));
    for (int r = 0; r < kRobots; ++r) {
        const auto& row = j["robots"][r];
        EXPECT_EQ(row["id"].get<int>(), r);
        EXPECT_GT(row["keyframes"].get<int>(), 100);
        const auto& rmse = row["rmse"];
        for (const char* key : {"odometry", "one_time_alignment", "local_search", "certified"}) {
            ASSERT_TRUE(rmse.contains(key)) << key;
            EXPECT_GE(rmse[key].get<double>(), 0.0) << key;
        }
        EXPECT_LT(rmse["certified"].get<double>(), rmse["odometry"].get<double>()) << "robot " << r;
        EXPECT_LT(rmse["certified"].get<double>(), rmse["one_time_alignment"].get<double>())
            << "robot " << r;
    }
}

TEST_F(Demo, WritesTrajectoriesGraphMeshAndPlot) {
    ASSERT_EQ(run_->exit_code, 0) << run_->out;
    const auto report = nlohmann::json::parse(ReadFile(*dir_ / "report.json"));
    int total = 0;
    for (int r = 0; r < kRobots; ++r) {
        const int keyframes = report["robots"][r]["keyframes"].get<int>();
        total += keyframes;
        for (const char* method :
             {"ground_truth", "odometry", "one_time_alignment", "local_search", "certified"}) {
            const auto path = *dir_ / ("robot" + std::to_string(r) + "_" + method + ".tum");
            const std::string tum = ReadFile(path);
            int rows = 0;
            std::istringstream in(tum);
            for (std::string line; std::getline(in, line);) {
                if (line.empty() || line[0] == '#') continue;
                std::istringstream fields(line);
                int count = 0;
                for (double v; fields >> v;) ++count;
                EXPECT_EQ(count, 8) << path << ": " << line;
                ++rows;
            }
            EXPECT_EQ(rows, keyframes) << path;
        }
    }
    const std::string g2o = ReadFile(*dir_ / "joint_graph.g2o");
    EXPECT_EQ(CountLines(g2o, "VERTEX_SE3:QUAT "), total);
    EXPECT_GE(CountLines(g2o, "EDGE_SE3:QUAT "), total - kRobots + 1);
    const std::string ply = ReadFile(*dir_ / "mesh.ply");
    EXPECT_EQ(ply.rfind("ply\nformat binary_little_endian 1.0\n", 0), 0u);
    EXPECT_GT(ply.size(), 10000u);
    const std::string svg = ReadFile(*dir_ / "trajectories.svg");
    EXPECT_EQ(svg.rfind("<svg ", 0), 0u);
    EXPECT_NE(svg.find("</svg>"), std::string::npos);
    EXPECT_GE(CountLines(svg, "<polyline "), 4 * 2 * kRobots);
}

TEST(DemoOptions, KeyframesFlagShortensTheMission) {
    const auto dir = std::filesystem::temp_directory_path() /
                     ("certislam_demo_short_" + std::to_string(getpid()));
    const auto run =
        testing::Shell(std::string(CERTISLAM_BINARY) + " demo --scenario city --keyframes " +
                       std::to_string(kShortKeyframes) +
                       " --voxel 0 --pipeline --quiet --json --out " + dir.string());
    std::filesystem::remove_all(dir);
    ASSERT_EQ(run.exit_code, 0) << run.out;
    const auto j = nlohmann::json::parse(run.out);
    ASSERT_EQ(j["robots"].size(), static_cast<size_t>(kRobots));
    for (const auto& row : j["robots"]) EXPECT_EQ(row["keyframes"].get<int>(), kShortKeyframes);
}

TEST(DemoOptions, RejectsAnUnknownCertificateMode) {
    const auto run =
        testing::Shell(std::string(CERTISLAM_BINARY) + " demo --certificate central 2>&1");
    EXPECT_NE(run.exit_code, 0);
    EXPECT_NE(run.out.find("--certificate"), std::string::npos) << run.out;
}

TEST(DemoOptions, RejectsZeroRobots) {
    const auto run = testing::Shell(std::string(CERTISLAM_BINARY) + " demo --robots 0 2>&1");
    EXPECT_NE(run.exit_code, 0);
}

}  // namespace
}  // namespace certislam
