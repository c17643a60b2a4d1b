// Multi-robot CSV reader (dpgo_ros tunnels format): one measurements.csv per robot folder.
#include "slam/io/multirobot_io.h"

#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <vector>

namespace certislam::slam {
namespace {

constexpr const char* kHeader =
    "robot_src,pose_src,robot_dst,pose_dst,qx,qy,qz,qw,tx,ty,tz,kappa,tau,is_known_inlier,weight";
constexpr int kColumns = 15;
constexpr int kMaxId = 100'000'000;  ///< as the g2o reader's pose ids

struct CsvEdge {
    PoseId src;
    PoseId dst;
    Eigen::Matrix3d R;
    Eigen::Vector3d t;
    double kappa = 0.0;
    double tau = 0.0;
    bool inlier = false;
};

// Parses one data row; returns an error reason or an empty string.
std::string ParseRow(const std::string& line, CsvEdge* edge) {
    std::vector<double> v;
    std::stringstream in(line);
    std::string cell;
    while (std::getline(in, cell, ',')) {
        char* end = nullptr;
        const double x = std::strtod(cell.c_str(), &end);
        if (end == cell.c_str() || (*end != '\0' && *end != '\r')) {
            return "not a number: '" + cell + "'";
        }
        if (!std::isfinite(x)) return "non-finite value: '" + cell + "'";
        v.push_back(x);
    }
    if (static_cast<int>(v.size()) != kColumns) {
        return "expected " + std::to_string(kColumns) + " columns, got " + std::to_string(v.size());
    }
    for (int k : {0, 1, 2, 3}) {
        if (v[k] < 0 || v[k] != std::floor(v[k]) || v[k] > kMaxId) {
            return "bad robot or pose id (a whole number in [0, " + std::to_string(kMaxId) + "])";
        }
    }
    edge->src = PoseId{static_cast<int>(v[0]), static_cast<int>(v[1])};
    edge->dst = PoseId{static_cast<int>(v[2]), static_cast<int>(v[3])};
    std::string why;
    const auto R = QuaternionRotation(v[4], v[5], v[6], v[7], &why);
    if (!R) return why;
    edge->R = *R;
    edge->t = Eigen::Vector3d(v[8], v[9], v[10]);
    edge->kappa = v[11];
    edge->tau = v[12];
    edge->inlier = v[13] != 0.0;
    return CheckMeasurementRange(edge->t, edge->kappa, edge->tau);
}

PoseGraphReadResult Fail(PoseGraphReadResult::Status status, std::string error) {
    PoseGraphReadResult r;
    r.status = status;
    r.error = std::move(error);
    return r;
}

}  // namespace

PoseGraphReadResult ReadMultiRobotCsv(const std::string& dir) {
    using Status = PoseGraphReadResult::Status;
    std::vector<CsvEdge> edges;
    std::set<std::array<int, 4>> inter_seen;
    std::map<int, int> poses_of_robot;  // robot -> max index + 1
    int robots = 0;
    for (;; ++robots) {
        const std::string path = dir + "/robot" + std::to_string(robots) + "/measurements.csv";
        if (!std::filesystem::exists(path)) break;
        std::ifstream in(path);
        if (!in) return Fail(Status::kFileError, path + ": cannot open file");
        std::string line;
        int line_no = 0;
        while (std::getline(in, line)) {
            ++line_no;
            if (!line.empty() && line.back() == '\r') line.pop_back();
            if (line.find_first_not_of(" \t") == std::string::npos) continue;
            if (line_no == 1) {
                if (line != kHeader)
                    return Fail(Status::kParseError, path + ":1: unexpected header");
                continue;
            }
            CsvEdge e;
            if (const std::string reason = ParseRow(line, &e); !reason.empty()) {
                std::string where = path;
                where += ":" + std::to_string(line_no) + ": ";
                return Fail(Status::kParseError, where + reason);
            }
            if (e.src.robot != e.dst.robot &&
                !inter_seen.insert({e.src.robot, e.src.index, e.dst.robot, e.dst.index}).second) {
                continue;  // the other robot's file already listed this inter-robot edge
            }
            for (const PoseId& p : {e.src, e.dst}) {
                poses_of_robot[p.robot] = std::max(poses_of_robot[p.robot], p.index + 1);
            }
            edges.push_back(e);
        }
    }
    if (robots == 0) return Fail(Status::kFileError, dir + ": no robot0/measurements.csv");
    // A connected graph has at most edges + 1 poses: checked before allocating the ids.
    std::size_t poses = 0;
    for (const auto& [robot, count] : poses_of_robot) poses += static_cast<std::size_t>(count);
    if (edges.empty() || poses > edges.size() + 1) {
        return Fail(Status::kDisconnected, dir + ": graph is not connected (" +
                                               std::to_string(poses) + " poses, " +
                                               std::to_string(edges.size()) + " edges)");
    }
    PoseGraphReadResult result;
    PoseGraph& graph = result.graph;
    graph.d = 3;
    std::map<int, int> offset;
    for (const auto& [robot, count] : poses_of_robot) {
        offset[robot] = graph.n;
        for (int k = 0; k < count; ++k) graph.ids.push_back(PoseId{robot, k});
        graph.n += count;
    }
    for (const CsvEdge& c : edges) {
        RelativePoseMeasurement e;
        e.i = offset[c.src.robot] + c.src.index;
        e.j = offset[c.dst.robot] + c.dst.index;
        e.R = c.R;
        e.t = c.t;
        e.kappa = c.kappa;
        e.tau = c.tau;
        e.is_known_inlier = c.inlier;
        graph.edges.push_back(std::move(e));
    }
    if (!IsConnected(graph)) return Fail(Status::kDisconnected, dir + ": graph is not connected");
    return result;
}

}  // namespace certislam::slam
