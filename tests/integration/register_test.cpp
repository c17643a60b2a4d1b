// Runs the real `certislam register` on real scans (hdl_pair_fast_gicp, KITTI 00) and on bad
// files, and checks what it prints.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numbers>
#include <string>

#include "tests/data_paths.h"
#include "tests/integration/shell.h"
#include "tests/scratch_dir.h"

namespace {

using certislam::testing::Shell;

const std::string kLidar = certislam::test_data::DataPath("lidar/");
constexpr double kHdlMaxTranslationM = 0.05;  // issue 4: fast_gicp's pair, 0.2 m voxels
constexpr double kHdlMaxRotationDeg = 1.0;

Eigen::Matrix4d ReadMatrix4(const std::string& path) {
    std::ifstream in(path);
    Eigen::Matrix4d T;
    for (int k = 0; k < 16; ++k) in >> T(k / 4, k % 4);
    return T;
}

TEST(RegisterCommand, HdlPairJsonMatchesReference) {
    const auto run = Shell(std::string(CERTISLAM_BINARY) + " register " + kLidar +
                           "hdl_pair_fast_gicp/251371071.pcd " + kLidar +
                           "hdl_pair_fast_gicp/251370668.pcd --json --voxel 0.2");
    ASSERT_EQ(run.exit_code, 0) << run.out;
    const auto j = nlohmann::json::parse(run.out);
    ASSERT_EQ(j["T_target_source"].size(), 16u);
    Eigen::Matrix4d T;
    for (int k = 0; k < 16; ++k) T(k / 4, k % 4) = j["T_target_source"][k].get<double>();
    const Eigen::Matrix4d E = ReadMatrix4(kLidar + "hdl_pair_fast_gicp/relative.txt").inverse() * T;
    const double translation_m = E.topRightCorner<3, 1>().norm();
    EXPECT_LT(translation_m, kHdlMaxTranslationM);
    const double angle_deg = Eigen::AngleAxisd(Eigen::Matrix3d(E.topLeftCorner<3, 3>())).angle() *
                             180 / std::numbers::pi;
    EXPECT_LT(angle_deg, kHdlMaxRotationDeg);
    EXPECT_TRUE(j["converged"].get<bool>());
    EXPECT_EQ(j["status"], "accepted");
    EXPECT_GT(j["fitness"].get<double>(), 0.8);
    EXPECT_GE(j["sc_distance"].get<double>(), 0.0);
    EXPECT_LE(j["sc_distance"].get<double>(), 1.0);
    EXPECT_TRUE(j.contains("yaw_deg"));
}

TEST(RegisterCommand, KittiSamePlaceTextOutputHasEveryField) {
    const auto run = Shell(std::string(CERTISLAM_BINARY) + " register " + kLidar +
                           "kitti00_scancontext_samples/velodyne/000095.bin " + kLidar +
                           "kitti00_scancontext_samples/velodyne/000094.bin");
    ASSERT_EQ(run.exit_code, 0) << run.out;
    for (const char* field :
         {"T_target_source", "fitness", "sc_distance", "yaw_deg", "converged"}) {
        EXPECT_NE(run.out.find(field), std::string::npos) << field << " missing:\n" << run.out;
    }
    EXPECT_NE(run.out.find("status accepted"), std::string::npos) << run.out;
}

TEST(RegisterCommand, TruncatedFileIsAnErrorNamingIt) {
    const auto dir = certislam::testing::ScratchDir();
    std::filesystem::create_directories(dir);
    const auto bad = (dir / "truncated.pcd").string();
    {
        std::ofstream out(bad);
        out << "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 100\n"
               "HEIGHT 1\nPOINTS 100\nDATA ascii\n1 2 3\n";
    }
    const auto run = Shell(std::string(CERTISLAM_BINARY) + " register " + bad + " " + kLidar +
                           "hdl_pair_fast_gicp/251370668.pcd 2>&1");
    EXPECT_NE(run.exit_code, 0);
    EXPECT_NE(run.out.find(bad), std::string::npos) << run.out;
    const auto missing =
        Shell(std::string(CERTISLAM_BINARY) + " register /nonexistent/a.bin " + bad + " 2>&1");
    EXPECT_NE(missing.exit_code, 0);
    EXPECT_NE(missing.out.find("/nonexistent/a.bin"), std::string::npos) << missing.out;
}

}  // namespace
