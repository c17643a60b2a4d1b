// Runs the real `certislam solve` on a small benchmark file (JSON keys, f*, certificate, output
// file, progress on stderr) and on malformed files (file:line, non-zero exit).
#include <gtest/gtest.h>

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

constexpr double kTinyGridFStar = 18.5193868731;  ///< data/g2o/README.md
constexpr double kRelGap = 1e-6;

std::string TempPath(const std::string& name) {
    const auto dir = certislam::testing::ScratchDir();
    std::filesystem::create_directories(dir);
    return (dir / name).string();
}

std::string TinyGrid() { return certislam::test_data::G2oPath("tinyGrid3D.g2o"); }

nlohmann::json SolveJson(const std::string& args) {
    const ShellResult r =
        Shell(std::string(CERTISLAM_BINARY) + " solve " + args + " --json 2>/dev/null");
    EXPECT_EQ(r.exit_code, 0) << r.out;
    return nlohmann::json::parse(r.out);
}

TEST(SolveCommand, JsonHasEveryKeyAndReachesTheCertifiedOptimum) {
    for (int robots : {1, 3}) {
        const nlohmann::json j = SolveJson(TinyGrid() + " --robots " + std::to_string(robots));
        for (const char* key :
             {"cost", "objective", "certified", "verdict", "lambda_min", "lower_bound",
              "suboptimality_bound", "relative_suboptimality_bound", "rank", "iterations",
              "seconds", "peak_rss_mb", "poses", "edges", "robots"}) {
            EXPECT_TRUE(j.contains(key)) << key;
        }
        EXPECT_LE(std::abs(j["cost"].get<double>() - kTinyGridFStar) / kTinyGridFStar, kRelGap);
        EXPECT_TRUE(j["certified"].get<bool>());
        EXPECT_EQ(j["verdict"].get<std::string>(), "certified");
        EXPECT_LE(j["relative_suboptimality_bound"].get<double>(), 1e-6);
        EXPECT_LE(j["lower_bound"].get<double>(), kTinyGridFStar * (1.0 + kRelGap));
        EXPECT_EQ(j["poses"].get<int>(), 9);
        EXPECT_EQ(j["edges"].get<int>(), 11);
        EXPECT_EQ(j["robots"].get<int>(), robots);
        EXPECT_GE(j["suboptimality_bound"].get<double>(), -kRelGap * kTinyGridFStar);
        EXPECT_LE(j["suboptimality_bound"].get<double>(), 1e-3 * kTinyGridFStar);
        EXPECT_GT(j["peak_rss_mb"].get<double>(), 0.0);
    }
}

TEST(SolveCommand, LmBaselineIsJudgedByTheCertificate) {
    const nlohmann::json j = SolveJson(TinyGrid() + " --method lm");
    EXPECT_TRUE(j["certified"].is_boolean());
    EXPECT_GE(j["cost"].get<double>(), kTinyGridFStar * (1.0 - kRelGap));
    // One spelling of the verdict, and a bound only with a proven one.
    const std::string verdict = j["verdict"].get<std::string>();
    EXPECT_TRUE(verdict == "certified" || verdict == "not optimal" || verdict == "not critical" ||
                verdict == "inconclusive")
        << verdict;
    EXPECT_EQ(j["certified"].get<bool>(), verdict == "certified");
    EXPECT_EQ(j.contains("suboptimality_bound"), j.contains("lower_bound"));
    if (verdict == "certified") {
        EXPECT_TRUE(j.contains("suboptimality_bound"));
    }
    if (verdict == "not optimal" || verdict == "not critical") {
        EXPECT_FALSE(j.contains("suboptimality_bound"));
    }
}

// The same solution, judged against a relative bound no floating-point run can prove.
TEST(SolveCommand, MaxRelativeBoundIsTheCertifiedThreshold) {
    const ShellResult r = Shell(std::string(CERTISLAM_BINARY) + " solve " + TinyGrid() +
                                " --max-relative-bound 1e-15 --json 2>/dev/null");
    EXPECT_NE(r.exit_code, 0);
    const nlohmann::json j = nlohmann::json::parse(r.out);
    EXPECT_FALSE(j["certified"].get<bool>());
    EXPECT_EQ(j["verdict"].get<std::string>(), "inconclusive");
    EXPECT_GT(j["relative_suboptimality_bound"].get<double>(), 1e-15);
    EXPECT_NE(j["reason"].get<std::string>().find("exceeds 1e-15"), std::string::npos) << j;
    for (const char* bad : {"0", "1", "-1e-6"}) {
        const ShellResult b = Shell(std::string(CERTISLAM_BINARY) + " solve " + TinyGrid() +
                                    " --max-relative-bound " + bad + " 2>&1");
        EXPECT_NE(b.exit_code, 0) << bad;
        EXPECT_NE(b.out.find("--max-relative-bound"), std::string::npos) << b.out;
    }
}

TEST(SolveCommand, WritesTheSolutionAndAProgressLine) {
    const std::string out = TempPath("tiny_solved.g2o");
    std::filesystem::remove(out);
    const ShellResult r =
        Shell(std::string(CERTISLAM_BINARY) + " solve " + TinyGrid() + " --out " + out + " 2>&1");
    ASSERT_EQ(r.exit_code, 0) << r.out;
    EXPECT_NE(r.out.find("[solve"), std::string::npos) << r.out;  // progress on stderr
    EXPECT_NE(r.out.find("certified"), std::string::npos) << r.out;
    std::ifstream in(out);
    std::string line;
    int vertices = 0, edges = 0;
    while (std::getline(in, line)) {
        vertices += line.rfind("VERTEX_SE3:QUAT", 0) == 0;
        edges += line.rfind("EDGE_SE3:QUAT", 0) == 0;
    }
    EXPECT_EQ(vertices, 9);
    EXPECT_EQ(edges, 11);
}

TEST(SolveCommand, MalformedFileFailsWithFileAndLine) {
    const std::string bad = TempPath("bad.g2o");
    std::ofstream(bad) << "EDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\n\nEDGE_SE2 1 2 1 0 0 1 0 0 1 0\n";
    const ShellResult r = Shell(std::string(CERTISLAM_BINARY) + " solve " + bad + " 2>&1");
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.out.find(bad + ":3:"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("too few numbers"), std::string::npos) << r.out;
}

TEST(SolveCommand, MissingFileAndBadOptionsFail) {
    EXPECT_NE(Shell(std::string(CERTISLAM_BINARY) + " solve /no/such.g2o 2>&1").exit_code, 0);
    EXPECT_NE(Shell(std::string(CERTISLAM_BINARY) + " solve " + TinyGrid() + " --method nope 2>&1")
                  .exit_code,
              0);
    EXPECT_NE(Shell(std::string(CERTISLAM_BINARY) + " solve " + TinyGrid() + " --robots 99 2>&1")
                  .exit_code,
              0);
}

}  // namespace
