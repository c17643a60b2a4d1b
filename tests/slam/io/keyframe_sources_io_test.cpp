// Keyframe sources on disk: the real KAIST03 SC-A-LOAM folder and the KITTI 00 samples, and
// corrupt copies of them whose errors must name the file (and line) and the fault.
#include "slam/io/keyframe_sources_io.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include "tests/data_paths.h"
#include "tests/scratch_dir.h"

namespace certislam::slam {
namespace {

namespace fs = std::filesystem;
const std::string kLidar = test_data::DataPath("lidar/");
const std::string kKaist = kLidar + "mulran_kaist03_keyframes";
const std::string kKitti = kLidar + "kitti00_scancontext_samples";

fs::path Scratch(const std::string& name) {
    const fs::path dir = certislam::testing::ScratchDir() / name;
    fs::remove_all(dir);
    fs::create_directories(dir);
    return dir;
}

// A copy of the first `scans` KAIST03 keyframes with their poses/times files.
fs::path KaistCopy(const std::string& name, int scans) {
    const fs::path dir = Scratch(name);
    fs::create_directories(dir / "Scans");
    for (int k = 0; k < scans; ++k) {
        char file[32];
        std::snprintf(file, sizeof file, "%06d.pcd", k);
        fs::copy_file(fs::path(kKaist) / "Scans" / file, dir / "Scans" / file);
    }
    fs::copy_file(fs::path(kKaist) / "optimized_poses.txt", dir / "optimized_poses.txt");
    fs::copy_file(fs::path(kKaist) / "times.txt", dir / "times.txt");
    return dir;
}

TEST(KeyframeSources, KaistFolderHasTwentyOneKeyframesWithPosesTimesAndClouds) {
    const auto r = ReadScLioSamFolder(kKaist);
    ASSERT_TRUE(r.ok()) << r.error;
    ASSERT_EQ(r.keyframes.size(), 21u);
    EXPECT_GT(r.keyframes[0].cloud->size(), 36000u);  // README: ~36.5-37.1 k points
    EXPECT_LT(r.keyframes[0].cloud->size(), 37200u);
    // times.txt line 1, 1567410201.7452047 s; a double holds it to ~0.24 us.
    EXPECT_NEAR(static_cast<double>(r.keyframes[0].stamp_ns), 1567410201745204700.0, 1e3);
    EXPECT_GT(r.keyframes[20].stamp_ns, r.keyframes[0].stamp_ns);
    // README: 0 -> 20 spans a 23.6 m path; straight-line distance a little less.
    const double d =
        (r.keyframes[20].T_odom_sensor.translation() - r.keyframes[0].T_odom_sensor.translation())
            .norm();
    EXPECT_GT(d, 20.0);
    EXPECT_LT(d, 23.7);
    EXPECT_EQ(r.keyframes[7].index, 7);
}

TEST(KeyframeSources, SelectionAndLimitApply) {
    KeyframeSourceOptions options;
    options.load_clouds = false;
    options.select_keyframes = true;
    options.selection.min_translation_m = 5.0;
    options.robot = 3;
    const auto r = ReadScLioSamFolder(kKaist, options);
    ASSERT_TRUE(r.ok()) << r.error;
    EXPECT_GE(r.keyframes.size(), 4u);  // ~23.6 m at >= 5 m spacing
    EXPECT_LE(r.keyframes.size(), 6u);
    EXPECT_EQ(r.keyframes[1].robot, 3);
    EXPECT_EQ(r.keyframes[1].cloud, nullptr);
    EXPECT_GT(r.source_indices[1], 1);
    options.select_keyframes = false;
    options.max_keyframes = 2;
    EXPECT_EQ(ReadScLioSamFolder(kKaist, options).keyframes.size(), 2u);
}

TEST(KeyframeSources, TruncatedScanNamesTheFile) {
    const fs::path dir = KaistCopy("truncated", 3);
    const fs::path scan = dir / "Scans" / "000001.pcd";
    fs::resize_file(scan, fs::file_size(scan) / 2);
    const auto r = ReadScLioSamFolder(dir.string());
    EXPECT_EQ(r.status, KeyframeSourceResult::Status::kBadScan);
    EXPECT_NE(r.error.find("000001.pcd"), std::string::npos) << r.error;
    EXPECT_TRUE(r.keyframes.empty());
}

TEST(KeyframeSources, MalformedPoseLineNamesFileAndLine) {
    const fs::path dir = KaistCopy("badpose", 2);
    {
        std::ofstream out(dir / "optimized_poses.txt");
        out << "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 zero 0 0 1 0\n";
    }
    const auto r = ReadScLioSamFolder(dir.string());
    EXPECT_EQ(r.status, KeyframeSourceResult::Status::kBadPoses);
    EXPECT_NE(r.error.find("optimized_poses.txt:2"), std::string::npos) << r.error;
    EXPECT_NE(r.error.find("zero"), std::string::npos) << r.error;
}

TEST(KeyframeSources, FewerTimesThanScansIsAnError) {
    const fs::path dir = KaistCopy("fewtimes", 3);
    {
        std::ofstream out(dir / "times.txt");
        out << "1.0\n2.0\n";
    }
    const auto r = ReadScLioSamFolder(dir.string());
    EXPECT_EQ(r.status, KeyframeSourceResult::Status::kBadTimes);
    EXPECT_NE(r.error.find("times.txt"), std::string::npos) << r.error;
    EXPECT_NE(r.error.find("000002.pcd"), std::string::npos) << r.error;
}

TEST(KeyframeSources, MissingFolderIsCannotOpen) {
    const auto r = ReadScLioSamFolder("/nonexistent/folder");
    EXPECT_EQ(r.status, KeyframeSourceResult::Status::kCannotOpen);
    EXPECT_NE(r.error.find("/nonexistent/folder"), std::string::npos);
}

TEST(KeyframeSources, KittiSamplesGiveVelodynePosesThroughTheCalibration) {
    const auto r = ReadKittiOdometryFolder(kKitti, kKitti + "/poses_cam0_subset.txt",
                                           kKitti + "/calib_Tr_velo_to_cam0_seq00.txt");
    ASSERT_TRUE(r.ok()) << r.error;
    ASSERT_EQ(r.keyframes.size(), 4u);
    EXPECT_EQ(r.source_indices[0], 94);
    EXPECT_EQ(r.source_indices[3], 199);
    // README: 94 and 95 are 0.47 m apart, 94 and 198 about 58 m.
    const auto p = [&](int k) { return r.keyframes[k].T_odom_sensor.translation(); };
    EXPECT_NEAR((p(1) - p(0)).norm(), 0.47, 0.02);
    EXPECT_NEAR((p(2) - p(0)).norm(), 58.0, 3.0);
    // The velodyne frame is z-up: its z axis maps to KITTI cam0's -y (up) direction.
    const Eigen::Vector3d up = r.keyframes[0].T_odom_sensor.rotation().col(2);
    EXPECT_LT(up.y(), -0.99);
    EXPECT_GT(r.keyframes[0].cloud->size(), 120000u);
    EXPECT_EQ(r.keyframes[1].stamp_ns, 9'500'000'000);  // no times.txt: 0.1 s per frame
}

TEST(KeyframeSources, KittiCalibrationWithoutTrNamesTheFile) {
    const fs::path dir = Scratch("kitti_calib");
    {
        std::ofstream out(dir / "calib.txt");
        out << "P0: 1 0 0 0 0 1 0 0 0 0 1 0\n";
    }
    const auto r = ReadKittiOdometryFolder(kKitti, kKitti + "/poses_cam0_subset.txt",
                                           (dir / "calib.txt").string());
    EXPECT_EQ(r.status, KeyframeSourceResult::Status::kBadPoses);
    EXPECT_NE(r.error.find("calib.txt"), std::string::npos) << r.error;
    EXPECT_NE(r.error.find("Tr"), std::string::npos) << r.error;
}

}  // namespace
}  // namespace certislam::slam
