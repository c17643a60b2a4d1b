// The g2o reader on the real benchmark files and their quirks (data/g2o/README.md), and its
// rejections with file:line on malformed input.
#include "slam/io/g2o_io.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>

#include "slam/backend/connection_laplacian.h"
#include "tests/data_paths.h"
#include "tests/scratch_dir.h"

namespace certislam::slam {
namespace {

constexpr double kWeightTolerance = 1e-9;  ///< relative, kappa/tau after a write/read round trip

using test_data::G2oPath;

std::string WriteTemp(const std::string& name, const std::string& text) {
    const auto dir = certislam::testing::ScratchDir();
    std::filesystem::create_directories(dir);
    const std::string path = (dir / name).string();
    std::ofstream(path) << text;
    return path;
}

struct FileCase {
    const char* file;
    int d;
    int n;
    int m;
};

class RealFile : public ::testing::TestWithParam<FileCase> {};

TEST_P(RealFile, PosesAndEdgesAsTheReadmeCounts) {
    const FileCase c = GetParam();
    const PoseGraphReadResult read = ReadG2o(G2oPath(c.file));
    ASSERT_TRUE(read.ok()) << read.error;
    EXPECT_EQ(read.graph.d, c.d);
    EXPECT_EQ(read.graph.n, c.n);
    EXPECT_EQ(static_cast<int>(read.graph.edges.size()), c.m);
    for (const auto& e : read.graph.edges) {
        ASSERT_GT(e.kappa, 0.0);
        ASSERT_GT(e.tau, 0.0);
    }
}

INSTANTIATE_TEST_SUITE_P(
    Readme, RealFile,
    ::testing::Values(
        FileCase{"tinyGrid3D.g2o", 3, 9, 11}, FileCase{"smallGrid3D.g2o", 3, 125, 297},
        FileCase{"sphere2500.g2o", 3, 2500, 4949}, FileCase{"torus3D.g2o", 3, 5000, 9048},
        FileCase{"parking-garage.g2o", 3, 1661, 6275}, FileCase{"cubicle.g2o", 3, 5750, 16869},
        FileCase{"CSAIL.g2o", 2, 1045, 1172}, FileCase{"intel.g2o", 2, 1728, 2512},
        FileCase{"manhattan.g2o", 2, 3500, 5453}, FileCase{"city10000.g2o", 2, 10000, 20687},
        FileCase{"MIT.g2o", 2, 808, 827}, FileCase{"input_INTEL_g2o.g2o", 2, 1228, 1483},
        FileCase{"kitti_00.g2o", 2, 4541, 4677}, FileCase{"kitti_06.g2o", 2, 1101, 1150},
        FileCase{"kitti_07.g2o", 2, 1101, 1106}, FileCase{"kitti_08.g2o", 2, 4071, 4070},
        FileCase{"kitti_09.g2o", 2, 1591, 1592}, FileCase{"variants/dpgo/CSAIL.g2o", 2, 1045, 1171},
        FileCase{"variants/dpgo/kitti_00.g2o", 2, 4541, 4676}),
    [](const ::testing::TestParamInfo<FileCase>& info) {
        std::string s = info.param.file;
        std::replace_if(
            s.begin(), s.end(), [](char ch) { return !std::isalnum(ch); }, '_');
        return s;
    });

TEST(G2oQuirks, BlankLinesDoNotRepeatThePreviousEdge) {
    // kitti_00 has blank lines at 4541 and 4679: other readers re-add the edge before them.
    const PoseGraphReadResult read = ReadG2o(G2oPath("kitti_00.g2o"));
    ASSERT_TRUE(read.ok()) << read.error;
    const auto& edges = read.graph.edges;
    int repeats = 0;
    for (size_t k = 1; k < edges.size(); ++k) {
        if (edges[k].i == edges[k - 1].i && edges[k].j == edges[k - 1].j &&
            edges[k].t == edges[k - 1].t) {
            ++repeats;
        }
    }
    // The file's one exact duplicate (3825 915, lines 4677-4678) is adjacent and is followed by
    // the blank line 4679: a reader that re-adds the previous edge there makes it three copies.
    EXPECT_EQ(repeats, 1);
    const auto copies = std::count_if(edges.begin(), edges.end(),
                                      [](const auto& e) { return e.i == 3825 && e.j == 915; });
    EXPECT_EQ(copies, 2);
    EXPECT_EQ(edges.size(), 4677u);
}

TEST(G2oQuirks, ExactDuplicateEdgesAreKept) {
    const PoseGraphReadResult read = ReadG2o(G2oPath("CSAIL.g2o"));
    ASSERT_TRUE(read.ok()) << read.error;
    const auto count = std::count_if(read.graph.edges.begin(), read.graph.edges.end(),
                                     [](const auto& e) { return e.i == 323 && e.j == 855; });
    EXPECT_EQ(count, 2);
}

TEST(G2oQuirks, ReversedEdgesAndMultiEdgesKeptAsWritten) {
    const PoseGraphReadResult read = ReadG2o(G2oPath("cubicle.g2o"));
    ASSERT_TRUE(read.ok()) << read.error;
    const auto reversed = std::count_if(read.graph.edges.begin(), read.graph.edges.end(),
                                        [](const auto& e) { return e.i > e.j; });
    EXPECT_EQ(reversed, 992);
}

TEST(G2oQuirks, MissingVertexLinesGiveNFromTheEdgesAndNoGuess) {
    const PoseGraphReadResult csail = ReadG2o(G2oPath("CSAIL.g2o"));  // no VERTEX lines
    ASSERT_TRUE(csail.ok()) << csail.error;
    EXPECT_EQ(csail.graph.n, 1045);
    EXPECT_FALSE(csail.graph.initial_guess.has_value());
    const PoseGraphReadResult mit = ReadG2o(G2oPath("MIT.g2o"));  // one VERTEX per pose
    ASSERT_TRUE(mit.ok()) << mit.error;
    ASSERT_TRUE(mit.graph.initial_guess.has_value());
    EXPECT_EQ(mit.graph.initial_guess->cols(), 3 * 808);
}

TEST(G2oQuirks, FixLinesAndCommentsAreAccepted) {
    const std::string path = WriteTemp("fix.g2o",
                                       "# comment\nFIX 0\n\n"
                                       "EDGE_SE2 0 1 1 0 0 10 0 0 10 0 100\n"
                                       "EDGE_SE2 2 1 1 0 0.1 10 0 0 10 0 100\n");
    const PoseGraphReadResult read = ReadG2o(path);
    ASSERT_TRUE(read.ok()) << read.error;
    EXPECT_EQ(read.graph.n, 3);
    ASSERT_EQ(read.graph.edges.size(), 2u);
    EXPECT_EQ(read.graph.edges[1].i, 2);  // i > j kept
    EXPECT_NEAR(read.graph.edges[0].tau, 10.0, 1e-12);
    EXPECT_NEAR(read.graph.edges[0].kappa, 100.0, 1e-12);
}

struct BadCase {
    const char* name;
    const char* text;
    const char* line;    ///< expected ":<line>:" in the message
    const char* reason;  ///< expected words of the reason
};

class Rejects : public ::testing::TestWithParam<BadCase> {};

TEST_P(Rejects, WithFileLineAndReason) {
    const BadCase c = GetParam();
    const std::string path = WriteTemp(std::string(c.name) + ".g2o", c.text);
    const PoseGraphReadResult read = ReadG2o(path);
    ASSERT_FALSE(read.ok());
    EXPECT_NE(read.error.find(path + c.line), std::string::npos) << read.error;
    EXPECT_NE(read.error.find(c.reason), std::string::npos) << read.error;
}

INSTANTIATE_TEST_SUITE_P(
    Malformed, Rejects,
    ::testing::Values(
        BadCase{"unknown", "EDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\nEDGE_FOO 1 2\n", ":2:", "unknown"},
        BadCase{"short", "\nEDGE_SE2 0 1 1 0 0 1 0 0 1 0\n", ":2:", "too few"},
        BadCase{"nan", "EDGE_SE2 0 1 nan 0 0 1 0 0 1 0 1\n", ":1:", "non-finite"},
        BadCase{"inf", "EDGE_SE2 0 1 1 0 0 1 0 0 1 0 inf\n", ":1:", "non-finite"},
        BadCase{"notpd", "EDGE_SE2 0 1 1 0 0 1 2 0 1 0 1\n", ":1:", "not positive definite"},
        BadCase{"zerokappa", "EDGE_SE2 0 1 1 0 0 1 0 0 1 0 0\n", ":1:", "not positive definite"},
        BadCase{"word", "EDGE_SE2 0 1 1 0 zero 1 0 0 1 0 1\n", ":1:", "not a number"},
        BadCase{"mixed",
                "EDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\nEDGE_SE3:QUAT 1 2 0 0 0 0 0 0 1 1 0 0 0 0 0 1 0 0 "
                "0 0 1 0 0 0 1 0 0 1 0 1\n",
                ":2:", "mixes"}),
    [](const ::testing::TestParamInfo<BadCase>& info) { return std::string(info.param.name); });

TEST(G2oRejects, DisconnectedGraph) {
    const std::string path = WriteTemp("split.g2o",
                                       "EDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\n"
                                       "EDGE_SE2 2 3 1 0 0 1 0 0 1 0 1\n");
    const PoseGraphReadResult read = ReadG2o(path);
    EXPECT_EQ(read.status, PoseGraphReadResult::Status::kDisconnected);
    EXPECT_NE(read.error.find("not connected"), std::string::npos) << read.error;
}

TEST(G2oRejects, MissingFile) {
    const PoseGraphReadResult read = ReadG2o(G2oPath("no_such_file.g2o"));
    EXPECT_EQ(read.status, PoseGraphReadResult::Status::kFileError);
}

TEST(G2oWrite, RoundTripKeepsWeightsAndCost) {
    const PoseGraphReadResult read = ReadG2o(G2oPath("smallGrid3D.g2o"));
    ASSERT_TRUE(read.ok()) << read.error;
    ASSERT_TRUE(read.graph.initial_guess.has_value());
    const std::string path = WriteTemp("roundtrip.g2o", "");
    std::string error;
    ASSERT_TRUE(WriteG2o(path, read.graph, *read.graph.initial_guess, &error)) << error;
    const PoseGraphReadResult again = ReadG2o(path);
    ASSERT_TRUE(again.ok()) << again.error;
    ASSERT_EQ(again.graph.edges.size(), read.graph.edges.size());
    for (size_t k = 0; k < read.graph.edges.size(); ++k) {
        const auto& a = read.graph.edges[k];
        const auto& b = again.graph.edges[k];
        ASSERT_EQ(a.i, b.i);
        ASSERT_EQ(a.j, b.j);
        EXPECT_NEAR(b.kappa / a.kappa, 1.0, kWeightTolerance);
        EXPECT_NEAR(b.tau / a.tau, 1.0, kWeightTolerance);
    }
    ASSERT_TRUE(again.graph.initial_guess.has_value());
    const double f0 = Objective(read.graph, *read.graph.initial_guess);
    const double f1 = Objective(again.graph, *again.graph.initial_guess);
    // Written quaternions are unit; the file's are off by up to 1e-6: the costs agree to that.
    EXPECT_NEAR(f1 / f0, 1.0, 1e-4);
}

}  // namespace
}  // namespace certislam::slam
