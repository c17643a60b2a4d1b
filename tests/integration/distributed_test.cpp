// Distributed mode equals local mode: the same small simulated two-robot mission run by
// `certislam run` (one process, inproc) and by two `certislam robot` processes over tcp loopback
// with CURVE keys from `certislam keygen` gives the same trajectories within 1e-6, certified,
// with the TSDF mappers running in both modes: robot 0's mesh (its own and robot 1's submaps, sent
// over tcp) lies within sensor range of the trajectories.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <Eigen/Core>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "actors/durable_log.h"
#include "certislam/v1/loop_closure.pb.h"
#include "tests/integration/shell.h"
#include "transport/message.h"

namespace certislam {
namespace {

constexpr double kEqualTolerance = 1e-6;  ///< metres and quaternion components
constexpr int kKeyframes = 45;
constexpr double kSensorRange_m = 90.0;  ///< the simulator's LiDAR max range (SimulatorConfig)
constexpr double kMeshSlack_m = 1.0;     ///< marching cubes / truncation band beyond a hit

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

/// Vertices of a binary PLY written by `certislam robot` (float32 x y z first); empty on error.
std::vector<Eigen::Vector3d> ReadPlyVertices(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    std::size_t count = 0;
    for (std::string line; std::getline(in, line) && line != "end_header";) {
        if (line.rfind("element vertex ", 0) == 0) count = std::stoul(line.substr(15));
    }
    std::vector<Eigen::Vector3d> out;
    for (std::size_t i = 0; i < count && in; ++i) {
        float xyz[3];
        in.read(reinterpret_cast<char*>(xyz), sizeof(xyz));
        if (in) out.emplace_back(xyz[0], xyz[1], xyz[2]);
    }
    return out;
}

/// Largest distance from a mesh vertex to the nearest keyframe position of the TUM files.
double FarthestFromTrajectories(const std::vector<Eigen::Vector3d>& vertices,
                                const std::vector<std::string>& tum_paths) {
    std::vector<Eigen::Vector3d> positions;
    for (const auto& path : tum_paths) {
        for (const auto& row : ReadTum(path)) {
            if (row.size() == 8) positions.emplace_back(row[1], row[2], row[3]);
        }
    }
    if (positions.empty()) return INFINITY;
    double worst = 0.0;
    for (const auto& v : vertices) {
        double nearest = INFINITY;
        for (const auto& p : positions) nearest = std::min(nearest, (v - p).norm());
        worst = std::max(worst, nearest);
    }
    return worst;
}

/// True when a plain tcp socket can bind 127.0.0.1:port now.
bool Bindable(int port) {
    const int fd = socket(AF_INET, SOCK_STREAM, 0);
    if (fd < 0) return false;
    const int one = 1;
    setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof(one));
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(static_cast<std::uint16_t>(port));
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    const bool ok = bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof(address)) == 0;
    close(fd);
    return ok;
}

/// A base port for two robots (base .. base + kPortsUsed - 1 all free now), below Linux's
/// ephemeral range (32768-60999). Inside it, a ZeroMQ client that retries a port not yet bound
/// (a peer starting, or restarting after kill -9) can be given that very port as its source and
/// connect to itself (TCP self-connection): the robot that should bind it then fails with
/// "Address already in use" (and its peer waits until its timeout), and
/// libzmq 4.3 drops such a connection for good (zeromq/libzmq#4588).
int FreePortBase() {
    constexpr int kLowest = 20000, kHighest = 32000, kStride = 20;  // below 32768
    constexpr int kPortsUsed = 20;  ///< two robots, ten ports each (base_port + 0..7 used)
    std::mt19937 rng(static_cast<unsigned>(getpid()));
    for (int attempt = 0; attempt < 100; ++attempt) {
        const int base =
            kLowest + static_cast<int>(rng() % ((kHighest - kLowest) / kStride)) * kStride;
        bool free = true;
        for (int p = base; p < base + kPortsUsed && free; ++p) free = Bindable(p);
        if (free) return base;
    }
    return kLowest;
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

    /// CURVE keys robot0 and robot1 in the test folder, by `certislam keygen`.
    void MakeKeys() {
        for (int r = 0; r < 2; ++r) {
            const auto keygen = testing::Shell(Binary() + " keygen --out " +
                                               (dir_ / ("robot" + std::to_string(r))).string());
            ASSERT_EQ(keygen.exit_code, 0) << keygen.out;
        }
    }

    /// The team's configuration; `solver_mode` sets solver.mode (empty: the default).
    std::string WriteConfig(const std::string& solver_mode = "") {
        const int base = FreePortBase();
        std::ofstream out(dir_ / "team.json");
        out << R"({"robots": [0, 1],
  "source": {"kind": "simulator", "seed": 1, "max_keyframes": )"
            << kKeyframes << R"(},
  "solver": {"rank": 5, "rel_grad_tol": 1e-9)"
            << (solver_mode.empty() ? "" : R"(, "mode": ")" + solver_mode + "\"") << R"(},
  "matcher": {"query_stride": 3},
  "mapping": {"voxel_m": 0.4},
  "network": {
    "0": {"host": "127.0.0.1", "base_port": )"
            << base << R"(, "public_key": "robot0.pub", "secret_key": "robot0.key"},
    "1": {"host": "127.0.0.1", "base_port": )"
            << base + 10 << R"(, "public_key": "robot1.pub", "secret_key": "robot1.key"}}})";
        return (dir_ / "team.json").string();
    }

    /// Robot 0 (exit code in r0.rc, log `out0`) and the restarted robot 1 (`run`) certified, with
    /// the trajectories of the single-process run `local` (folders local/ and restarted/).
    void ExpectRestartedTeamEqualsLocal(const testing::ShellResult& run,
                                        const testing::ShellResult& local,
                                        const std::string& out0) {
        std::ifstream rc0(dir_ / "r0.rc");
        int code0 = -1;
        rc0 >> code0;
        EXPECT_EQ(code0, 0) << out0;
        EXPECT_NE(run.out.find("\"certified\": true"), std::string::npos) << run.out;
        for (int r = 0; r < 2; ++r) {
            const std::string name = "robot" + std::to_string(r) + ".tum";
            EXPECT_LT(MaxDifference((dir_ / "local" / name).string(),
                                    (dir_ / "restarted" / name).string()),
                      kEqualTolerance)
                << name << "\nlocal:\n"
                << local.out << "\nrobot 0:\n"
                << out0 << "\nrobot 1 (restarted):\n"
                << run.out;
        }
    }

    std::filesystem::path dir_;
};

TEST_F(Distributed, TwoRobotProcessesOverTcpEqualTheSingleProcessRun) {
    MakeKeys();
    if (HasFatalFailure()) return;
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
            << name << "\nlocal:\n"
            << local.out << "\nrobot 0:\n"
            << both.out << "\nrobot 1:\n"
            << out1;
    }

    // Robot 0 (the anchor) fused its own submaps and robot 1's; robot 1 sent each of its
    // submaps' bytes once and fused none of robot 0's (mapping.team_map "anchor").
    EXPECT_NE(both.out.find("\"peer_submaps\": "), std::string::npos) << both.out;
    EXPECT_EQ(both.out.find("\"peer_submaps\": 0"), std::string::npos) << both.out;
    EXPECT_NE(out1.find("\"peer_submaps\": 0"), std::string::npos) << out1;
    const auto mesh0 = ReadPlyVertices(dir_ / "distributed" / "robot0.mesh.ply");
    const auto mesh1 = ReadPlyVertices(dir_ / "distributed" / "robot1.mesh.ply");
    ASSERT_GT(mesh1.size(), 1000u);
    EXPECT_GT(mesh0.size(), mesh1.size());  // robot 1's submaps are in robot 0's mesh
    const std::vector<std::string> tums{(dir_ / "local" / "robot0.tum").string(),
                                        (dir_ / "local" / "robot1.tum").string()};
    EXPECT_LT(FarthestFromTrajectories(mesh0, tums), kSensorRange_m + kMeshSlack_m);
}

TEST_F(Distributed, RobotKilledAndRestartedMidMissionRejoinsTheCertifiedOptimum) {
    MakeKeys();
    if (HasFatalFailure()) return;
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
    std::ifstream log0(dir_ / "r0.log");
    const std::string out0((std::istreambuf_iterator<char>(log0)), {});
    ASSERT_EQ(run.exit_code, 0) << run.out << "\nrobot 0:\n" << out0;
    EXPECT_GT(std::filesystem::file_size(dir_ / "logs" / "robot1.keyframes.log"), 0u);
    ExpectRestartedTeamEqualsLocal(run, local, out0);
}

// solver.mode rounds: robot 1 is killed once its rounds converged (the team's: they converge
// together) and started again. Robot 0, converged, hears robot 1's new incarnation and opens a new
// round session; both sweep again from their iterates (robot 1 from its replayed graph), and the
// team certifies the single-process run's trajectories. Before: robot 1 waited at round 0 of the
// old session, where robot 0 had stopped, until its timeout.
TEST_F(Distributed, RobotKilledAfterTheTeamsRoundsConvergedRejoinsThemWhenRestarted) {
    MakeKeys();
    if (HasFatalFailure()) return;
    const std::string config = WriteConfig("rounds");
    const auto local = testing::Shell(Binary() + " run " + config + " --json --timeout 120 --out " +
                                      (dir_ / "local").string() + " 2>&1");
    ASSERT_EQ(local.exit_code, 0) << local.out;
    const std::string robot = Binary() + " robot " + config + " --json --timeout 90 --out " +
                              (dir_ / "restarted").string() + " --log-dir " +
                              (dir_ / "logs").string();
    const std::string first = (dir_ / "r1_first.log").string();
    // The kill waits for robot 1's progress line to say its rounds converged (at most 60 s).
    const auto run = testing::Shell(
        "(" + robot + " --id 0 > " + (dir_ / "r0.log").string() + " 2>&1; echo $? > " +
        (dir_ / "r0.rc").string() + ") & " + robot + " --id 1 --progress 0.05 > " + first +
        " 2>&1 & victim=$!; for i in $(seq 1200); do grep -q 'team rounds (converged)' " + first +
        " && break; sleep 0.05; done; kill -9 $victim; sleep 1; " + robot +
        " --id 1 2>&1; rc1=$?; wait; exit $rc1");
    std::ifstream log0(dir_ / "r0.log"), log1(first);
    const std::string out0((std::istreambuf_iterator<char>(log0)), {});
    const std::string out1((std::istreambuf_iterator<char>(log1)), {});
    ASSERT_NE(out1.find("team rounds (converged)"), std::string::npos) << out1;
    ASSERT_EQ(run.exit_code, 0) << run.out << "\nrobot 0:\n" << out0;
    ExpectRestartedTeamEqualsLocal(run, local, out0);
}

// The team certified and left; robot 1 then restarts alone from its durable log. It replays the
// same graph and ends certified with the checkpointed state, equal to the team's result, instead
// of waiting for peers that are gone until its timeout (exit 3).
TEST_F(Distributed, RobotRestartedAfterItsTeamLeftEndsWithTheCertifiedStateOfItsLog) {
    MakeKeys();
    if (HasFatalFailure()) return;
    const std::string config = WriteConfig();
    const std::string robot =
        Binary() + " robot " + config + " --json --log-dir " + (dir_ / "logs").string() + " --id ";
    const auto team =
        testing::Shell("(" + robot + "0 --timeout 120 --out " + (dir_ / "team").string() + " > " +
                       (dir_ / "r0.log").string() + " 2>&1) & " + robot + "1 --timeout 120 --out " +
                       (dir_ / "team").string() + " 2>&1; rc1=$?; wait; exit $rc1");
    ASSERT_EQ(team.exit_code, 0) << team.out;
    EXPECT_NE(team.out.find("\"restored_from_log\": false"), std::string::npos) << team.out;
    {  // the robot's report says how its synchronous rounds went
        std::ifstream in(dir_ / "team" / "robot1.report.json");
        const auto report = nlohmann::json::parse(in, nullptr, false);
        ASSERT_FALSE(report.is_discarded());
        const auto& rounds = report["robots"][0]["rounds"];
        EXPECT_TRUE(rounds["converged"].get<bool>()) << rounds;
        EXPECT_FALSE(rounds["gave_up"].get<bool>()) << rounds;
        EXPECT_GT(rounds["swept"].get<int>(), 0) << rounds;
        EXPECT_EQ(rounds["rejected_proposals"].get<int>(), 0) << rounds;
        EXPECT_LE(rounds["overlap_ends"].get<int>(), rounds["restarts"].get<int>()) << rounds;
    }

    // Alone: no peer answers, so only the log can end it before the timeout.
    const auto alone =
        testing::Shell(robot + "1 --timeout 60 --out " + (dir_ / "alone").string() + " 2>&1");
    ASSERT_EQ(alone.exit_code, 0) << alone.out;
    EXPECT_NE(alone.out.find("\"certified\": true"), std::string::npos) << alone.out;
    EXPECT_NE(alone.out.find("\"restored_from_log\": true"), std::string::npos) << alone.out;
    EXPECT_LT(MaxDifference((dir_ / "team" / "robot1.tum").string(),
                            (dir_ / "alone" / "robot1.tum").string()),
              kEqualTolerance)
        << "team:\n"
        << team.out << "\nalone:\n"
        << alone.out;

    // A log whose graph differs from its checkpoint's (an inter-robot loop taken out, which the
    // robot cannot find again alone) is not restored: the robot waits for its peers again and
    // says so at its timeout.
    const std::string loops_log = (dir_ / "logs" / "robot1.loops.log").string();
    const actors::DurableLogRead read = actors::ReadDurableLog(loops_log);
    std::filesystem::remove(loops_log);
    {
        actors::DurableLog rewritten(loops_log, read.identity);
        bool dropped = false;
        for (const auto& m : read.messages) {
            const auto loop = transport::Unpack<v1::LoopClosure>(m);
            if (!dropped && loop && loop->pose_a().robot_id() != loop->pose_b().robot_id()) {
                dropped = true;
                continue;
            }
            rewritten.Append(m);
        }
        ASSERT_TRUE(dropped);
    }
    const auto changed =
        testing::Shell(robot + "1 --timeout 8 --out " + (dir_ / "changed").string() + " 2>&1");
    EXPECT_EQ(changed.exit_code, 3) << changed.out;
    EXPECT_NE(changed.out.find("\"restored_from_log\": false"), std::string::npos) << changed.out;
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
