// `certislam solve --out`: the solution keeps the input's frame (pose 0 where the input's VERTEX
// line puts it) and is written as g2o, TUM or KITTI by the file's extension.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "tests/data_paths.h"
#include "tests/integration/shell.h"
#include "tests/scratch_dir.h"

namespace certislam {
namespace {

using testing::Shell;

constexpr double kSamePose = 1e-6;  ///< printed poses of the same pose

std::string TempPath(const std::string& name) {
    const auto dir = certislam::testing::ScratchDir();
    std::filesystem::create_directories(dir);
    return (dir / name).string();
}

/// The numbers of the first line of `path` that starts with `prefix` (after the prefix).
std::vector<double> FirstLine(const std::string& path, const std::string& prefix) {
    std::ifstream in(path);
    std::string line;
    while (std::getline(in, line)) {
        if (line.rfind(prefix, 0) != 0) continue;
        std::istringstream fields(line.substr(prefix.size()));
        std::vector<double> out;
        for (double v; fields >> v;) out.push_back(v);
        return out;
    }
    return {};
}

int Lines(const std::string& path) {
    std::ifstream in(path);
    int n = 0;
    for (std::string line; std::getline(in, line);) n += !line.empty() && line[0] != '#';
    return n;
}

/// tinyGrid3D moved so that its pose 0 is not the identity (the solver's gauge would lose it).
std::string MovedTinyGrid() {
    const std::string path = TempPath("moved.g2o");
    std::ifstream in(test_data::G2oPath("tinyGrid3D.g2o"));
    std::ofstream out(path);
    out.precision(17);
    for (std::string line; std::getline(in, line);) {
        if (line.rfind("VERTEX_SE3:QUAT 0 ", 0) == 0) {
            out << "VERTEX_SE3:QUAT 0 5 -3 2 0.5 0.5 0.5 0.5\n";  // 120 deg about (1,1,1)
        } else {
            out << line << "\n";
        }
    }
    return path;
}

TEST(SolveOutput, KeepsTheInputsPoseZeroInEveryFormat) {
    const std::string input = MovedTinyGrid();
    const std::string solve = std::string(CERTISLAM_BINARY) + " solve " + input + " --quiet --out ";
    const std::string g2o = TempPath("out.g2o"), tum = TempPath("out.tum"),
                      kitti = TempPath("out.kitti");
    for (const auto& out : {g2o, tum, kitti}) {
        const auto r = Shell(solve + out + " 2>&1");
        ASSERT_EQ(r.exit_code, 0) << r.out;
    }
    const std::vector<double> expected{5, -3, 2, 0.5, 0.5, 0.5, 0.5};
    const auto v0 = FirstLine(g2o, "VERTEX_SE3:QUAT 0 ");
    ASSERT_EQ(v0.size(), 7u);
    const double sign = v0[6] < 0 ? -1.0 : 1.0;  // q and -q are the same rotation
    for (int i = 0; i < 7; ++i) EXPECT_NEAR(v0[i] * (i >= 3 ? sign : 1.0), expected[i], kSamePose);
    const auto t0 = FirstLine(tum, "0 ");
    ASSERT_EQ(t0.size(), 7u);
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(t0[i], expected[i], kSamePose);
    EXPECT_EQ(Lines(tum), 9);
    // KITTI: row-major [R t]; R of q = (0.5, 0.5, 0.5, 0.5) permutes the axes (x -> y -> z).
    const auto k0 = FirstLine(kitti, "");
    ASSERT_EQ(k0.size(), 12u);
    const std::vector<double> kitti0{0, 0, 1, 5, 1, 0, 0, -3, 0, 1, 0, 2};
    for (int i = 0; i < 12; ++i) EXPECT_NEAR(k0[i], kitti0[i], kSamePose) << i;
    EXPECT_EQ(Lines(kitti), 9);
}

TEST(SolveOutput, UnknownExtensionFailsBeforeSolving) {
    const auto r = Shell(std::string(CERTISLAM_BINARY) + " solve " + MovedTinyGrid() + " --out " +
                         TempPath("out.xyz") + " 2>&1");
    EXPECT_EQ(r.exit_code, 1) << r.out;
    EXPECT_NE(r.out.find("unknown output format '.xyz'"), std::string::npos) << r.out;
}

}  // namespace
}  // namespace certislam
