// Crafted files an attacker or a corrupt disk could hand the readers: sizes that overflow, counts
// that would allocate gigabytes, quaternions off the unit sphere, absurd values. Each must end in
// an error naming the file (and line or byte offset) and the rule, never a crash or a huge
// allocation. The files are written by the tests.
#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "slam/io/cloud_io.h"
#include "slam/io/g2o_io.h"
#include "slam/io/multirobot_io.h"
#include "slam/io/trajectory_io.h"
#include "tests/data_paths.h"

namespace certislam::slam {
namespace {

namespace fs = std::filesystem;
using Cloud = CloudReadResult::Status;

fs::path Dir() {
    const fs::path dir =
        fs::temp_directory_path() / ("certislam_hostile_" + std::to_string(::getpid()));
    fs::create_directories(dir);
    return dir;
}

std::string Write(const std::string& name, const std::string& bytes) {
    const fs::path path = Dir() / name;
    fs::create_directories(path.parent_path());
    std::ofstream(path, std::ios::binary) << bytes;
    return path.string();
}

bool Contains(const std::string& text, const std::string& part) {
    return text.find(part) != std::string::npos;
}

// The crash: 16384 FIELDS x COUNT 2^20 x SIZE 8 is a 2^37-byte record; POINTS 2^27
// makes POINTS x record = 2^64, which wraps to 0 in size_t and passed the old bounds check.
TEST(HostileInput, PcdRecordSizeOverflowIsRefused) {
    std::string fields = "FIELDS x y z", sizes = "SIZE", types = "TYPE", counts = "COUNT";
    for (int f = 0; f < 16384; ++f) {
        if (f >= 3) fields += " f" + std::to_string(f);
        sizes += " 8";
        types += " F";
        counts += " 1048576";
    }
    const std::string path = Write(
        "overflow.pcd", "VERSION 0.7\n" + fields + "\n" + sizes + "\n" + types + "\n" + counts +
                            "\nPOINTS 134217728\nDATA binary\n" + std::string(64, '\0'));
    const CloudReadResult r = ReadPcd(path);
    EXPECT_EQ(r.status, Cloud::kTruncated);
    EXPECT_TRUE(Contains(r.error, path + ":7: binary data at byte ")) << r.error;
    EXPECT_TRUE(Contains(r.error, "overflows size_t")) << r.error;
    EXPECT_TRUE(r.cloud.empty());
}

TEST(HostileInput, PcdWidthTimesHeightOverflowIsRefused) {
    const std::string path = Write("wh.pcd",
                                   "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH "
                                   "4611686018427387904\nHEIGHT 8\nDATA binary\n");
    const CloudReadResult r = ReadPcd(path);
    EXPECT_EQ(r.status, Cloud::kBadHeader);
    EXPECT_TRUE(Contains(r.error, path + ":6: WIDTH x HEIGHT overflows")) << r.error;
}

// 4e9 bytes declared from 10 compressed ones: refused before allocating the 4 GB buffer.
TEST(HostileInput, PcdCompressedExpansionBeyondLzfIsRefused) {
    std::string data(18, '\0');
    const std::uint32_t compressed = 10, uncompressed = 4'000'000'008u;  // 333333334 x 12
    std::memcpy(data.data(), &compressed, 4);
    std::memcpy(data.data() + 4, &uncompressed, 4);
    const std::string header =
        "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 333333334\nDATA binary_compressed\n";
    const std::string path = Write("lzf.pcd", header + data);
    const CloudReadResult r = ReadPcd(path);
    EXPECT_EQ(r.status, Cloud::kBadData);
    EXPECT_TRUE(Contains(r.error, path + ":5: binary_compressed at byte " +
                                      std::to_string(header.size()) + ": 10 LZF bytes"))
        << r.error;
    EXPECT_TRUE(Contains(r.error, "LZF expands at most 88x")) << r.error;
}

TEST(HostileInput, PcdAsciiWithHugePointCountEndsTruncated) {
    const std::string path = Write("ascii.pcd",
                                   "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 4000000000000\n"
                                   "DATA ascii\n1 2 3\n");
    const CloudReadResult r = ReadPcd(path);
    EXPECT_EQ(r.status, Cloud::kTruncated);
    EXPECT_TRUE(Contains(r.error, path + ":6: POINTS 4000000000000 but only 1")) << r.error;
}

TEST(HostileInput, PlyVertexCountBeyondTheFileIsRefused) {
    const std::string header =
        "ply\nformat binary_little_endian 1.0\nelement vertex 4611686018427387904\n"
        "property float x\nproperty float y\nproperty float z\nend_header\n";
    const std::string path = Write("count.ply", header + std::string(24, '\0'));
    const CloudReadResult r = ReadPly(path);
    EXPECT_EQ(r.status, Cloud::kTruncated);
    EXPECT_TRUE(Contains(r.error, path + ": element 'vertex' at byte " +
                                      std::to_string(header.size()) +
                                      ": 4611686018427387904 records of at least 12 bytes do "
                                      "not fit in the 24 bytes left"))
        << r.error;
}

// An element without properties holds no bytes: 2^62 of them are skipped, not looped over.
TEST(HostileInput, PlyEmptyElementWithHugeCountIsSkipped) {
    const std::string path = Write("empty.ply",
                                   "ply\nformat binary_little_endian 1.0\nelement junk "
                                   "4611686018427387904\nelement vertex 1\nproperty float x\n"
                                   "property float y\nproperty float z\nend_header\n" +
                                       std::string(12, '\0'));
    const CloudReadResult r = ReadPly(path);
    ASSERT_TRUE(r.ok()) << r.error;
    EXPECT_EQ(r.cloud.size(), 1u);
}

TEST(HostileInput, PlyNegativeOrAbsurdListLengthIsRefused) {
    const std::string header =
        "element vertex 1\nproperty list char float n\nproperty float x\nproperty float y\n"
        "property float z\nend_header\n";
    const std::string binary = Write("neg.ply", "ply\nformat binary_little_endian 1.0\n" + header +
                                                    "\xff" + std::string(12, '\0'));
    const CloudReadResult b = ReadPly(binary);
    EXPECT_EQ(b.status, Cloud::kTruncated);
    EXPECT_TRUE(Contains(b.error, "negative list length")) << b.error;
    const std::string ascii =
        Write("huge.ply", "ply\nformat ascii 1.0\n" + header + "1e300 0 1 2 3\n");
    const CloudReadResult a = ReadPly(ascii);
    EXPECT_EQ(a.status, Cloud::kBadData);
    EXPECT_TRUE(Contains(a.error, ascii + ":9: list length 1e300")) << a.error;
}

std::string Edge(int i, int j, const std::string& pose) {
    return "EDGE_SE3:QUAT " + std::to_string(i) + " " + std::to_string(j) + " " + pose +
           " 100 0 0 0 0 0 100 0 0 0 0 100 0 0 0 400 0 0 400 0 400\n";
}

TEST(HostileInput, G2oQuaternionOffTheUnitSphereIsRefused) {
    for (const char* q : {"0 0 0 1.05", "0 0 0 1.03", "0 0 0 2", "0 0 0 0", "0.6 0 0 0.81"}) {
        const std::string path =
            Write("q.g2o", Edge(0, 1, "1 0 0 0 0 0 1") + Edge(1, 2, std::string("1 0 0 ") + q));
        const PoseGraphReadResult r = ReadG2o(path);
        EXPECT_EQ(r.status, PoseGraphReadResult::Status::kParseError) << q;
        EXPECT_TRUE(Contains(r.error, path + ":2: quaternion norm ")) << r.error;
    }
}

// Within rounding the quaternion is used as written (SE-Sync's convention, so the published f*
// apply); beyond rounding but within the tolerance it is normalised.
TEST(HostileInput, G2oQuaternionsWithinTheToleranceAreKept) {
    const std::string path = Write(
        "round.g2o", Edge(0, 1, "1 0 0 0 0 0.6 0.8000005") + Edge(1, 2, "1 0 0 0 0 0.6 0.8004"));
    const PoseGraphReadResult r = ReadG2o(path);
    ASSERT_TRUE(r.ok()) << r.error;
    EXPECT_NEAR(r.graph.edges[0].R(1, 0), 2 * 0.6 * 0.8000005, 1e-15);  // as written
    const Eigen::Matrix3d R = r.graph.edges[1].R;
    EXPECT_TRUE((R.transpose() * R).isIdentity(1e-12));  // normalised
    EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
    EXPECT_NEAR(R(1, 0), 2 * 0.6 * 0.8004 / (0.36 + 0.8004 * 0.8004), 1e-12);
}

TEST(HostileInput, G2oAbsurdValuesAreRefusedWithTheLine) {
    const std::string se2 = "EDGE_SE2 1 2 1 0 0 1 0 0 1 0 1\n";
    const std::string se3 = Edge(1, 2, "1 0 0 0 0 0 1");
    const std::vector<std::array<std::string, 3>> cases = {
        {se3, Edge(0, 1, "1e300 0 0 0 0 0 1"), "value '1e300' is beyond"},
        {se3, Edge(0, 1, "2e9 0 0 0 0 0 1"), "translation beyond"},
        {se2, "EDGE_SE2 0 1 1 0 0 1e16 0 0 1e16 0 1\n", "value '1e16' is beyond"},
        {se2, "EDGE_SE2 0 1 1 0 0 1e-300 0 0 1e-300 0 1\n", "not in [1e-12, 1e+15]"},
        {se3, "VERTEX_SE3:QUAT 0 0 0 0 0 0 0 0\n", "quaternion norm 0"},
    };
    for (const auto& [first, line, rule] : cases) {
        const std::string path = Write("absurd.g2o", first + line);
        const PoseGraphReadResult r = ReadG2o(path);
        EXPECT_EQ(r.status, PoseGraphReadResult::Status::kParseError) << line;
        EXPECT_TRUE(Contains(r.error, path + ":2: ")) << r.error;
        EXPECT_TRUE(Contains(r.error, rule)) << r.error;
    }
}

// Every benchmark file stays within the tolerances (quaternions, magnitudes, weights).
TEST(HostileInput, BenchmarkFilesPassTheChecks) {
    int files = 0;
    for (const auto& entry : fs::directory_iterator(test_data::DataPath("g2o"))) {
        if (entry.path().extension() != ".g2o") continue;
        const PoseGraphReadResult r = ReadG2o(entry.path().string());
        EXPECT_TRUE(r.ok()) << r.error;
        ++files;
    }
    EXPECT_GE(files, 15);
}

// One edge to pose 1e8 would size per-pose arrays for 1e8 poses; n <= edges + 1 refuses first.
TEST(HostileInput, G2oHugePoseIdIsDisconnectedNotAllocated) {
    const std::string path = Write("far.g2o", Edge(0, 100000000, "1 0 0 0 0 0 1"));
    const PoseGraphReadResult r = ReadG2o(path);
    EXPECT_EQ(r.status, PoseGraphReadResult::Status::kDisconnected);
    EXPECT_TRUE(Contains(r.error, "(100000001 poses, 1 edges)")) << r.error;
}

TEST(HostileInput, CsvIdsAndQuaternionsAreChecked) {
    const std::string header =
        "robot_src,pose_src,robot_dst,pose_dst,qx,qy,qz,qw,tx,ty,tz,kappa,tau,is_known_inlier,"
        "weight\n";
    const std::vector<std::pair<std::string, std::string>> cases = {
        {"0,0,0,1e300,0,0,0,1,1,0,0,1,1,1,1\n", "bad robot or pose id"},
        {"0,0,0,1,0,0,0,2,1,0,0,1,1,1,1\n", "quaternion norm 2"},
        {"0,0,0,1,0,0,0,1,1,0,0,1,1e20,1,1\n", "not in [1e-12, 1e+15]"},
    };
    for (size_t k = 0; k < cases.size(); ++k) {
        const std::string dir = (Dir() / ("csv" + std::to_string(k))).string();
        const std::string path =
            Write("csv" + std::to_string(k) + "/robot0/measurements.csv", header + cases[k].first);
        const PoseGraphReadResult r = ReadMultiRobotCsv(dir);
        EXPECT_EQ(r.status, PoseGraphReadResult::Status::kParseError) << k;
        EXPECT_TRUE(Contains(r.error, path + ":2: ")) << r.error;
        EXPECT_TRUE(Contains(r.error, cases[k].second)) << r.error;
    }
}

TEST(HostileInput, TrajectoryLineWithMillionsOfNumbersIsRefused) {
    std::string line;
    for (int k = 0; k < 1'000'000; ++k) line += "1 ";
    const std::string path = Write("long.tum", "0 0 0 0 0 0 0 1\n" + line + "\n");
    const TrajectoryReadResult r = ReadTrajectory(path, TrajectoryFormat::kTum);
    EXPECT_EQ(r.status, TrajectoryReadResult::Status::kParseError);
    EXPECT_TRUE(Contains(r.error, path + ":2: more than 12 numbers")) << r.error;
}

}  // namespace
}  // namespace certislam::slam
