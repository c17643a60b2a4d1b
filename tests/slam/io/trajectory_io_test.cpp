// TUM/KITTI round trips through real files and file:line errors on bad ones.
#include "slam/io/trajectory_io.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include "tests/scratch_dir.h"

namespace certislam::slam {
namespace {

constexpr double kRoundTrip = 1e-12;  ///< %.17g round trip of doubles

std::string TempPath(const std::string& name) {
    const auto dir = certislam::testing::ScratchDir();
    std::filesystem::create_directories(dir);
    return (dir / name).string();
}

void WriteText(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

Trajectory Sample() {
    Trajectory traj;
    for (int k = 0; k < 5; ++k) {
        StampedPose p;
        p.stamp_s = 1.5 + k;
        p.T_world_body.linear() =
            Eigen::AngleAxisd(0.3 * k, Eigen::Vector3d(0, 1, 1).normalized()).toRotationMatrix();
        p.T_world_body.translation() = Eigen::Vector3d(k, -2.0 * k, 0.25);
        traj.push_back(p);
    }
    return traj;
}

class TrajectoryIoRoundTrip : public ::testing::TestWithParam<TrajectoryFormat> {};

TEST_P(TrajectoryIoRoundTrip, WritesAndReadsBackTheSamePoses) {
    const std::string path = TempPath("roundtrip.txt");
    std::string error;
    ASSERT_TRUE(WriteTrajectory(path, Sample(), GetParam(), &error)) << error;
    const auto read = ReadTrajectory(path, GetParam());
    ASSERT_EQ(read.status, TrajectoryReadResult::Status::kOk) << read.error;
    ASSERT_EQ(read.trajectory.size(), 5u);
    for (size_t k = 0; k < 5; ++k) {
        EXPECT_TRUE(read.trajectory[k].T_world_body.isApprox(Sample()[k].T_world_body, kRoundTrip));
        const double stamp = GetParam() == TrajectoryFormat::kTum ? Sample()[k].stamp_s : k;
        EXPECT_DOUBLE_EQ(read.trajectory[k].stamp_s, stamp);
    }
}

INSTANTIATE_TEST_SUITE_P(Formats, TrajectoryIoRoundTrip,
                         ::testing::Values(TrajectoryFormat::kTum, TrajectoryFormat::kKitti),
                         [](const auto& info) {
                             return info.param == TrajectoryFormat::kTum ? "Tum" : "Kitti";
                         });

TEST(TrajectoryIo, TumCommentsAndBlankLinesAreSkipped) {
    const std::string path = TempPath("comments.tum");
    WriteText(path, "# stamp x y z qx qy qz qw\n\n0 1 2 3 0 0 0 1\n  \n1 1 2 3 0 0 0 2\n");
    const auto read = ReadTrajectory(path, TrajectoryFormat::kTum);
    ASSERT_EQ(read.status, TrajectoryReadResult::Status::kOk) << read.error;
    ASSERT_EQ(read.trajectory.size(), 2u);
    EXPECT_TRUE(read.trajectory[1].T_world_body.linear().isIdentity(1e-12));  // normalised
}

TEST(TrajectoryIo, BadLinesNameFileAndLine) {
    struct Case {
        std::string text, expected;
        TrajectoryFormat format;
    };
    const std::vector<Case> cases = {
        {"0 1 2 3 0 0 0 1\n0 1 2 3 0 0 1\n", ":2: expected 8 numbers", TrajectoryFormat::kTum},
        {"# c\n0 1 2 x 0 0 0 1\n", ":2: not a number: 'x'", TrajectoryFormat::kTum},
        {"0 1 2 nan 0 0 0 1\n", ":1: non-finite", TrajectoryFormat::kTum},
        {"0 1 2 3 0 0 0 0\n", ":1: zero quaternion", TrajectoryFormat::kTum},
        {"1 0 0 0 0 1 0 0 0 0 1\n", ":1: expected 12 numbers", TrajectoryFormat::kKitti},
        {"2 0 0 0 0 1 0 0 0 0 1 0\n", ":1: rotation block", TrajectoryFormat::kKitti},
        {"# only a comment\n", ":1: no poses", TrajectoryFormat::kTum},
    };
    for (size_t i = 0; i < cases.size(); ++i) {
        const std::string path = TempPath("bad" + std::to_string(i) + ".txt");
        WriteText(path, cases[i].text);
        const auto read = ReadTrajectory(path, cases[i].format);
        EXPECT_EQ(read.status, TrajectoryReadResult::Status::kParseError) << i;
        EXPECT_NE(read.error.find(path + cases[i].expected), std::string::npos) << read.error;
        EXPECT_TRUE(read.trajectory.empty());
    }
    EXPECT_EQ(ReadTrajectory(TempPath("missing.txt"), TrajectoryFormat::kTum).status,
              TrajectoryReadResult::Status::kCannotOpen);
}

}  // namespace
}  // namespace certislam::slam
