// The real commands on crafted files: no crash (the SIGSEGV on a PCD, SIGABRT on a g2o
// with |q| = 1.05), exit 1 with file:line and the rule; and `solve --robust` with a gross outlier
// loop closure rejects it and keeps odometry (it used to fail with "initial_shift = 0").
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "tests/data_paths.h"
#include "tests/integration/shell.h"
#include "tests/scratch_dir.h"

namespace {

using certislam::testing::Shell;
using certislam::testing::ShellResult;
using certislam::testing::WriteScratch;

constexpr double kTinyGridFStar = 18.5193868731;  ///< data/g2o/README.md

ShellResult Certislam(const std::string& args) {
    return Shell(std::string(CERTISLAM_BINARY) + " " + args + " 2>&1");
}

std::string TinyGridText() {
    std::ifstream in(certislam::test_data::G2oPath("tinyGrid3D.g2o"));
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

TEST(HostileInput, RegisterOnOverflowingPcdExitsOneNamingTheFile) {
    std::string fields = "FIELDS x y z", sizes = "SIZE", types = "TYPE", counts = "COUNT";
    for (int f = 0; f < 16384; ++f) {
        if (f >= 3) fields += " f" + std::to_string(f);
        sizes += " 8";
        types += " F";
        counts += " 1048576";
    }
    const std::string pcd = WriteScratch(
        "overflow.pcd", fields + "\n" + sizes + "\n" + types + "\n" + counts +
                            "\nPOINTS 134217728\nDATA binary\n" + std::string(64, '\0'));
    const ShellResult r = Certislam("register " + pcd + " " + pcd);
    EXPECT_EQ(r.exit_code, 1) << r.out;
    EXPECT_NE(r.out.find(pcd + ":6: binary data at byte"), std::string::npos) << r.out;
}

TEST(HostileInput, SolveRefusesNonUnitQuaternionsWithFileAndLine) {
    const std::string text = TinyGridText();
    for (const char* norm : {"1.05", "1.03", "2"}) {
        // Scale the quaternion of the file's first EDGE line to |q| = norm.
        const std::size_t at = text.find("EDGE_SE3:QUAT");
        ASSERT_NE(at, std::string::npos);
        const std::size_t end = text.find('\n', at);
        std::istringstream in(text.substr(at, end - at));
        std::string tok, line;
        for (int k = 0; in >> tok; ++k) {
            if (k >= 6 && k <= 9) tok = std::to_string(std::stod(tok) * std::stod(norm));
            line += (k ? " " : "") + tok;
        }
        const std::string path =
            WriteScratch("q.g2o", text.substr(0, at) + line + text.substr(end));
        const int line_no = 1 + static_cast<int>(std::count(text.begin(), text.begin() + at, '\n'));
        for (const char* method : {"rbcd", "lm"}) {
            const ShellResult r = Certislam("solve " + path + " --method " + method);
            EXPECT_EQ(r.exit_code, 1) << norm << " " << method << ": " << r.out;
            EXPECT_NE(r.out.find(path + ":" + std::to_string(line_no) + ": quaternion norm"),
                      std::string::npos)
                << r.out;
        }
    }
}

TEST(HostileInput, RobustSolveRejectsA500mLoopKeepsOdometryAndCertifies) {
    const std::string path =
        WriteScratch("outlier.g2o", TinyGridText() +
                                        "EDGE_SE3:QUAT 0 8 500 0 0 0 0 0 1 100 0 0 0 0 0 100 0 "
                                        "0 0 0 100 0 0 0 400 0 0 400 0 400\n");
    const ShellResult r =
        Shell(std::string(CERTISLAM_BINARY) + " solve " + path + " --robust --json 2>/dev/null");
    // The inlier graph GNC kept is solved and certified (exit 0).
    ASSERT_EQ(r.exit_code, 0) << r.out;
    const auto j = nlohmann::json::parse(r.out);
    EXPECT_TRUE(j["certified"].get<bool>()) << r.out;
    EXPECT_EQ(j["verdict"].get<std::string>(), "certified") << r.out;
    EXPECT_EQ(j["edges"].get<int>(), 12);
    // Only the 500 m loop (the last edge) is rejected: odometry and the grid's 3 loops stay.
    EXPECT_EQ(j["edges_used"].get<int>(), 11) << r.out;
    EXPECT_EQ(j["rejected_edges"], nlohmann::json::array({11})) << r.out;
    EXPECT_GT(j["cost"].get<double>(), 0.0);
}

}  // namespace
