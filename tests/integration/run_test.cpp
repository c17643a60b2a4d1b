// `certislam run` on real data, as a real process: the MulRan KAIST03 keyframe folder split into
// two robots (even / odd keyframes, robot 1's odometry moved by a rigid offset) through the whole
// actor graph over inproc: certified, robot 1's odometry frame recovered within 0.2 m / 1 degree,
// one TUM trajectory per robot with every keyframe. A simulated 2-robot team reports one
// certified objective with its proven lower bound. Bad source configurations fail naming the
// field.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <string>

#include "slam/io/keyframe_sources_io.h"
#include "slam/io/rosbag/rosbag_source_io.h"
#include "tests/data_paths.h"
#include "tests/integration/shell.h"

namespace certislam {
namespace {

const std::string kKaist = test_data::DataPath("lidar/mulran_kaist03_keyframes");
constexpr double kOffsetToleranceM = 0.2;    ///< recovered offset translation error
constexpr double kOffsetToleranceDeg = 1.0;  ///< recovered offset rotation error
constexpr int kKeyframesRobot0 = 11;         ///< the folder has 21 keyframes: 11 even
constexpr int kKeyframesRobot1 = 10;         ///< and 10 odd

std::string Binary() { return CERTISLAM_BINARY; }

int CountTumRows(const std::filesystem::path& path) {
    std::ifstream in(path);
    int rows = 0;
    for (std::string line; std::getline(in, line);) rows += !line.empty() && line[0] != '#';
    return rows;
}

class Run : public ::testing::Test {
  protected:
    void SetUp() override {
        dir_ =
            std::filesystem::temp_directory_path() / ("certislam_run_" + std::to_string(getpid()));
        std::filesystem::remove_all(dir_);
        std::filesystem::create_directories(dir_);
    }
    void TearDown() override { std::filesystem::remove_all(dir_); }

    std::string Write(const std::string& name, const std::string& text) {
        std::ofstream(dir_ / name) << text;
        return (dir_ / name).string();
    }
    testing::ShellResult RunConfig(const std::string& config, const std::string& extra = "") {
        return testing::Shell(Binary() + " run " + config + " --json --timeout 300 --out " +
                              (dir_ / "out").string() + extra + " 2>&1");
    }

    std::filesystem::path dir_;
};

TEST_F(Run, KaistSplitIntoTwoRobotsRecoversTheOffsetCertified) {
    const std::string config = Write("kaist.json", R"({"robots": [0, 1],
  "source": {"kind": "split", "path": ")" + kKaist + R"(", "robots": 2,
             "offset": {"xyz_m": [25.0, -12.0, 1.5], "rpy_deg": [0.0, 0.0, 40.0]}},
  "solver": {"rank": 5, "rel_grad_tol": 1e-9},
  "matcher": {"query_stride": 1, "intra_robot": false}})");
    const auto run = RunConfig(config);
    ASSERT_EQ(run.exit_code, 0) << run.out;
    const auto json_start = run.out.find('{');
    ASSERT_NE(json_start, std::string::npos) << run.out;
    const auto report = nlohmann::json::parse(run.out.substr(json_start));
    EXPECT_TRUE(report.at("certified").get<bool>()) << run.out;
    EXPECT_GE(report.at("inter_robot_loops").get<int>(), 1) << run.out;
    const auto& robots = report.at("robots");
    ASSERT_EQ(robots.size(), 2u);
    EXPECT_EQ(robots[0].at("keyframes").get<int>(), kKeyframesRobot0);
    EXPECT_EQ(robots[1].at("keyframes").get<int>(), kKeyframesRobot1);
    EXPECT_EQ(robots[1].at("anchor").get<int>(), 0) << "robot 1 never joined robot 0's frame";
    ASSERT_TRUE(robots[1].contains("offset_error_m")) << run.out;
    EXPECT_LT(robots[1].at("offset_error_m").get<double>(), kOffsetToleranceM) << run.out;
    EXPECT_LT(robots[1].at("offset_error_deg").get<double>(), kOffsetToleranceDeg) << run.out;
    EXPECT_LT(robots[0].at("offset_error_m").get<double>(), kOffsetToleranceM) << run.out;
    EXPECT_EQ(CountTumRows(dir_ / "out" / "robot0.tum"), kKeyframesRobot0);
    EXPECT_EQ(CountTumRows(dir_ / "out" / "robot1.tum"), kKeyframesRobot1);
    // The split's reference: each robot's keyframes' true poses, beside its estimate.
    EXPECT_EQ(CountTumRows(dir_ / "out" / "robot0.ground_truth.tum"), kKeyframesRobot0);
    EXPECT_EQ(CountTumRows(dir_ / "out" / "robot1.ground_truth.tum"), kKeyframesRobot1);
    EXPECT_TRUE(std::filesystem::exists(dir_ / "out" / "report.json"));
    std::printf(
        "KAIST03 split through `certislam run`: offset error %.4f m / %.4f deg, %d loops, "
        "%.2f s\n",
        robots[1].at("offset_error_m").get<double>(),
        robots[1].at("offset_error_deg").get<double>(), report.at("inter_robot_loops").get<int>(),
        report.at("seconds").get<double>());
}

TEST_F(Run, AnotherMissionsDurableLogIsRefusedNotReplayed) {
    // Same robot ids, another seed: the first mission's logs must not be replayed into the second.
    const auto mission = [&](int seed, const std::string& extra) {
        return Write("seed" + std::to_string(seed) + ".yaml",
                     "robots: [0]\nsource: {kind: simulator, max_keyframes: 8, seed: " +
                         std::to_string(seed) + "}\nlog_dir: " + (dir_ / "logs").string() + "\n" +
                         extra);
    };
    ASSERT_EQ(RunConfig(mission(1, "")).exit_code, 0);
    const std::string log = (dir_ / "logs" / "robot0.keyframes.log").string();
    const auto logged = std::filesystem::file_size(log);
    const auto refused = RunConfig(mission(2, ""));
    EXPECT_EQ(refused.exit_code, 1);
    EXPECT_NE(refused.out.find(log + ": written by another mission: 'source.seed: 1' in the log, "
                                     "'source.seed: 2' now"),
              std::string::npos)
        << refused.out;
    EXPECT_EQ(std::filesystem::file_size(log), logged);  // refused, and nothing lost
    const auto moved = RunConfig(mission(2, "log_stale: move_aside\n"));
    ASSERT_EQ(moved.exit_code, 0) << moved.out;
    EXPECT_EQ(std::filesystem::file_size(log + ".stale-1"), logged);
    // The new log is the second mission's: the same mission now replays it and certifies.
    EXPECT_EQ(RunConfig(mission(2, "")).exit_code, 0);
}

TEST_F(Run, TimeoutEndsTheProcessWhateverItsActorsAreDoing) {
    // A dense mission keeps the matcher in registrations and the mapper in TSDF integration far
    // past the deadline: the command still prints its report and ends soon after --timeout.
    const std::string config = Write("dense.yaml",
                                     "robots: [0, 1]\nsource: {kind: simulator, seed: 1, "
                                     "keyframe_spacing_m: 0.5}\n");
    const auto begin = std::chrono::steady_clock::now();
    const auto run = testing::Shell(Binary() + " run " + config + " --json --timeout 3 2>&1");
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - begin).count();
    EXPECT_EQ(run.exit_code, 3) << run.out;
    ASSERT_NE(run.out.find('{'), std::string::npos) << run.out;
    const auto report = nlohmann::json::parse(run.out.substr(run.out.find('{')));
    EXPECT_NE(report.at("verdict").get<std::string>(), "certified");
    EXPECT_LT(seconds, 3.0 + 2.0);  // 1 s of start-up and teardown, 1 s of slack on a busy CI
}

TEST_F(Run, SimulatedTeamReportsOneCertifiedObjectiveWithItsProvenBound) {
    constexpr double kMaxRelativeBound = 1e-6;  ///< CertificateConfig::max_relative_bound
    const std::string config = Write("sim.json", R"({"robots": [0, 1],
  "source": {"kind": "simulator", "seed": 1, "max_keyframes": 40},
  "solver": {"rank": 5, "rel_grad_tol": 1e-9},
  "matcher": {"query_stride": 3, "max_sc_distance": 0.2}})");
    const auto run = RunConfig(config);
    ASSERT_EQ(run.exit_code, 0) << run.out;
    const auto report = nlohmann::json::parse(run.out.substr(run.out.find('{')));
    EXPECT_EQ(report.at("verdict").get<std::string>(), "certified") << run.out;
    EXPECT_TRUE(report.at("certified").get<bool>());
    ASSERT_TRUE(report.at("lower_bound").is_number()) << "a certified report without its bound";
    const double objective = report.at("objective").get<double>();
    const double lower = report.at("lower_bound").get<double>();
    const double relative = report.at("relative_suboptimality_bound").get<double>();
    EXPECT_GT(objective, 0.0);
    EXPECT_LE(lower, objective);
    EXPECT_GE(lower, 0.0);
    EXPECT_LE(relative, kMaxRelativeBound);
    EXPECT_LE((objective - lower) / objective, kMaxRelativeBound);
    // One X, one graph: the duality gap is tr(X S X^T) >= -eta d n, tiny against f.
    EXPECT_GE(report.at("duality_gap").get<double>(), -kMaxRelativeBound * objective);
    // The keys of `solve --distributed`: the bound, team rounds, bytes by actor and robot.
    EXPECT_NEAR(report.at("suboptimality_bound").get<double>(), objective - lower,
                1e-9 * objective);
    const auto& bytes = report.at("bytes_between_robots");
    const auto total = bytes.at("total").get<std::uint64_t>();
    EXPECT_EQ(total, report.at("bytes_sent").get<std::uint64_t>());
    EXPECT_GT(total, 0u);
    for (const char* part : {"by_actor", "by_robot"}) {
        std::uint64_t sum = 0;
        for (const auto& [name, n] : bytes.at(part).items()) sum += n.get<std::uint64_t>();
        EXPECT_EQ(sum, total) << part;
    }
    EXPECT_GT(bytes.at("by_actor").at("solver").get<std::uint64_t>(), 0u);
    EXPECT_EQ(bytes.at("by_robot").size(), 2u);
    std::uint64_t most = 0;
    for (const auto& robot : report.at("robots")) {
        const auto id = std::to_string(robot.at("id").get<int>());
        most = std::max(most, report.at("iterations_by_robot").at(id).get<std::uint64_t>());
    }
    EXPECT_GT(most, 0u);
    EXPECT_EQ(report.at("iterations").get<std::uint64_t>(), most);
    EXPECT_GE(report.at("certificate_rounds").get<int>(), 1);
    EXPECT_GT(report.at("lanczos_steps").get<std::uint64_t>(), 0u);
}

TEST_F(Run, ShowsProgressAndWritesSnapshotsBeforeItEnds) {
    // A mission that runs past its 8 s timeout: after 4 s its report and trajectories are
    // already in --out (snapshots), and stderr has had progress lines.
    const std::string config = Write("long.yaml",
                                     "robots: [0, 1]\nsource: {kind: simulator, seed: 1, "
                                     "keyframe_spacing_m: 0.5}\nmapping: {enabled: false}\n");
    const std::string out = (dir_ / "snap").string();
    const auto run = testing::Shell(
        "(" + Binary() + " run " + config + " --timeout 8 --progress 1 --snapshot 1 --out " + out +
        " > " + (dir_ / "stdout").string() + " 2> " + (dir_ / "stderr").string() +
        " &) ; sleep 4; test -f " + out + "/report.json && test -f " + out +
        "/robot1.tum && echo SNAPSHOT-SEEN; sleep 6");
    EXPECT_NE(run.out.find("SNAPSHOT-SEEN"), std::string::npos) << run.out;
    std::ifstream err(dir_ / "stderr");
    const std::string progress((std::istreambuf_iterator<char>(err)), {});
    EXPECT_NE(progress.find("certislam run: 0/2 robots certified, "), std::string::npos)
        << progress;
    EXPECT_NE(progress.find(" block updates, "), std::string::npos) << progress;
    EXPECT_NE(progress.find(", last verdict: "), std::string::npos) << progress;
    // The solvers' phase: growing while keyframes arrive, team rounds once the graph is final.
    EXPECT_NE(progress.find("graph growing"), std::string::npos) << progress;
}

TEST_F(Run, KeyframeFolderPerRobotIsRead) {
    // Each robot reads its own folder (here the same one, capped): the keyframes arrive, and the
    // folder's poses are the reference of the per-robot evaluation.
    const std::string config = Write("folders.json", R"({"robots": [0],
  "source": {"kind": "keyframe_folder", "paths": {"0": ")" +
                                                         kKaist + R"("},
             "max_keyframes": 6},
  "matcher": {"intra_robot": false}})");
    const auto run = RunConfig(config);
    ASSERT_EQ(run.exit_code, 0) << run.out;
    const auto report = nlohmann::json::parse(run.out.substr(run.out.find('{')));
    EXPECT_EQ(report.at("robots")[0].at("keyframes").get<int>(), 6);
    EXPECT_LT(report.at("robots")[0].at("ate_rmse_own_alignment").get<double>(), 1e-3);
}

TEST_F(Run, MappingWritesTheMeshAndTheReference) {
    const std::string config = Write("mapping.json", R"({"robots": [0],
  "source": {"kind": "keyframe_folder", "paths": {"0": ")" +
                                                         kKaist + R"("},
             "max_keyframes": 6},
  "matcher": {"intra_robot": false},
  "mapping": {"enabled": true}})");
    const auto run = RunConfig(config);
    ASSERT_EQ(run.exit_code, 0) << run.out;
    const auto report = nlohmann::json::parse(run.out.substr(run.out.find('{')));
    const auto& robot = report.at("robots")[0];
    ASSERT_TRUE(robot.contains("mesh")) << run.out;
    EXPECT_GT(robot.at("mesh").at("triangles").get<int>(), 0) << run.out;
    std::ifstream mesh(dir_ / "out" / "robot0.mesh.ply", std::ios::binary);
    std::string magic(4, '\0');
    mesh.read(magic.data(), 4);
    EXPECT_EQ(magic, "ply\n");
    EXPECT_EQ(CountTumRows(dir_ / "out" / "robot0.ground_truth.tum"), 6);  // the folder's poses
}

TEST_F(Run, RosbagPerRobotIsRead) {
    // A LIO-SAM-like bag written with ROS 1's own bag library from real KAIST03 keyframes: `run`
    // reads it through the rosbag source, every keyframe arrives, and the bag's odometry is the
    // reference of the per-robot evaluation.
    constexpr int kKeyframes = 6;
    slam::KeyframeSourceResult folder = slam::ReadScLioSamFolder(kKaist, {});
    ASSERT_TRUE(folder.ok()) << folder.error;
    ASSERT_GE(static_cast<int>(folder.keyframes.size()), kKeyframes);
    folder.keyframes.resize(kKeyframes);
    slam::RosbagSourceConfig bag_config;
    bag_config.cloud_topic = "/robot0/cloud";
    bag_config.odometry_topic = "/robot0/odometry";
    const std::string bag = (dir_ / "robot0.bag").string();
    std::string error;
    ASSERT_TRUE(slam::WriteRosbagKeyframes(bag, folder.keyframes, bag_config, &error)) << error;
    const std::string config = Write("bag.json", R"({"robots": [0],
  "source": {"kind": "rosbag", "paths": {"0": ")" + bag +
                                                     R"("},
             "cloud_topic": "/robot0/cloud", "odometry_topic": "/robot0/odometry"},
  "matcher": {"intra_robot": false}})");
    const auto run = RunConfig(config);
    ASSERT_EQ(run.exit_code, 0) << run.out;
    const auto report = nlohmann::json::parse(run.out.substr(run.out.find('{')));
    EXPECT_EQ(report.at("robots")[0].at("keyframes").get<int>(), kKeyframes);
    EXPECT_LT(report.at("robots")[0].at("ate_rmse_own_alignment").get<double>(), 1e-3);

    // A topic the bag does not have fails naming the bag.
    const std::string wrong = Write("bag_wrong.json", R"({"robots": [0],
  "source": {"kind": "rosbag", "paths": {"0": ")" + bag + R"("}, "cloud_topic": "/nope"}})");
    const auto failed = RunConfig(wrong);
    EXPECT_NE(failed.exit_code, 0);
    EXPECT_NE(failed.out.find(bag), std::string::npos) << failed.out;
}

TEST_F(Run, KittiSequencePerRobotIsRead) {
    // Both robots drive the same four KITTI 00 frames (velodyne + ground truth + calibration):
    // every frame is a keyframe (selection off), and the ground truth is the reference.
    const std::string kitti = test_data::DataPath("lidar/kitti00_scancontext_samples");
    const std::string sequence = R"({"folder": ")" + kitti + R"(", "poses": ")" + kitti +
                                 R"(/poses_cam0_subset.txt", "calib": ")" + kitti +
                                 R"(/calib_Tr_velo_to_cam0_seq00.txt"})";
    const std::string config = Write("kitti.json", R"({"robots": [0, 1],
  "source": {"kind": "kitti", "select_keyframes": false,
             "sequences": {"0": )" + sequence + R"(, "1": )" +
                                                       sequence + R"(}},
  "matcher": {"query_stride": 1, "intra_robot": false}})");
    const auto run = RunConfig(config);
    ASSERT_EQ(run.exit_code, 0) << run.out;
    const auto report = nlohmann::json::parse(run.out.substr(run.out.find('{')));
    EXPECT_TRUE(report.at("certified").get<bool>());
    for (const auto& robot : report.at("robots")) {
        EXPECT_EQ(robot.at("keyframes").get<int>(), 4);
        EXPECT_TRUE(robot.contains("ate_rmse_own_alignment"));
    }
}

TEST_F(Run, BadSourcesFailNamingTheField) {
    const struct {
        const char* source;
        const char* field;
    } cases[] = {
        {R"({"kind": "split"})", "source.path"},
        {R"({"kind": "keyframe_folder", "paths": {"0": "/nonexistent"}})", "source.paths.1"},
        {R"({"kind": "kitti", "sequences": {"0": {"folder": "a"}, "1": {}}})", "source.sequences"},
        {R"({"kind": "split", "path": "/nonexistent/folder"})", "/nonexistent/folder"},
        {R"({"kind": "teleport"})", "source.kind"},
        {R"({"kind": "rosbag", "paths": {"0": "a.bag", "1": "b.bag"}, "cloud_frame": "map"})",
         "source.cloud_frame"},
        {R"({"kind": "split", "path": "x", "offset": {"xyz_m": [1, 2]}})", "source.offset.xyz_m"},
    };
    for (const auto& c : cases) {
        const std::string config =
            Write("bad.json", std::string(R"({"robots": [0, 1], "source": )") + c.source + "}");
        const auto run = RunConfig(config);
        EXPECT_EQ(run.exit_code, 1) << c.source << "\n" << run.out;
        EXPECT_NE(run.out.find(c.field), std::string::npos) << c.source << "\n" << run.out;
    }
}

}  // namespace
}  // namespace certislam
