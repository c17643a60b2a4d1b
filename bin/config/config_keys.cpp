// The team-configuration keys: each bound to its field of TeamConfig, with type, range and doc.
#include "bin/config/config_keys.h"

#include <yaml-cpp/yaml.h>

#include <charconv>
#include <cmath>
#include <filesystem>
#include <limits>
#include <stdexcept>
#include <type_traits>
#include <utility>

#include "bin/config/team_config.h"

namespace certislam::bin {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

/// An interval of numbers; open ends exclude their bound.
struct Range {
    double lo = -kInf;
    double hi = kInf;
    bool lo_open = false;
    bool hi_open = false;

    bool Contains(double v) const {
        return (lo_open ? v > lo : v >= lo) && (hi_open ? v < hi : v <= hi);
    }
};

std::string Number(double v) {
    char buffer[64];
    // Whole numbers as integers (to_chars' shortest form would print 100000 as 1e+05).
    const bool whole = std::isfinite(v) && std::abs(v) < 1e15 && v == std::floor(v);
    const auto end =
        whole ? std::to_chars(buffer, buffer + sizeof(buffer), static_cast<long long>(v)).ptr
              : std::to_chars(buffer, buffer + sizeof(buffer), v).ptr;
    return std::string(buffer, end);
}

std::string Text(const Range& r) {
    if (std::isinf(r.lo) && std::isinf(r.hi)) return "";
    if (std::isinf(r.hi)) return (r.lo_open ? "> " : ">= ") + Number(r.lo);
    if (std::isinf(r.lo)) return (r.hi_open ? "< " : "<= ") + Number(r.hi);
    return (r.lo_open ? "(" : "[") + Number(r.lo) + ", " + Number(r.hi) + (r.hi_open ? ")" : "]");
}

std::string Quote(const std::string& s) {
    std::string out = "\"";
    for (const char c : s) {
        if (c == '"' || c == '\\') out += '\\';
        out += c;
    }
    return out + "\"";
}

/// The scalar of `node` as T; `what` names the type in the error.
template <class T>
T Scalar(const YAML::Node& node, const std::string& what, bool quoted_ok = false) {
    if (node.IsNull()) throw std::invalid_argument("has no value (expected " + what + ")");
    if (!node.IsScalar()) {
        throw std::invalid_argument("must be " + what + ", not a " +
                                    (node.IsMap() ? "mapping" : "list"));
    }
    if (!quoted_ok && node.Tag() == "!") {
        throw std::invalid_argument("must be " + what + ", not the quoted string \"" +
                                    node.Scalar() + "\"");
    }
    try {
        return node.as<T>();
    } catch (const YAML::Exception&) {
        throw std::invalid_argument("must be " + what + ", not '" + node.Scalar() + "'");
    }
}

double InRange(double v, const Range& r) {
    if (!std::isfinite(v) || !r.Contains(v)) {
        throw std::invalid_argument(Number(v) + " is out of range " + Text(r));
    }
    return v;
}

/// An integer or real number field of type T.
template <class T, class G>
ConfigKey Num(std::string path, G get, Range range, std::string doc, std::string kinds = "") {
    constexpr bool kInt = std::is_integral_v<T>;
    ConfigKey key{std::move(path),  kInt ? "integer" : "number",
                  Text(range),      std::move(doc),
                  std::move(kinds), nullptr,
                  nullptr};
    key.show = [get](const TeamConfig& c, int r) {
        TeamConfig copy = c;
        return kInt ? std::to_string(static_cast<long long>(get(copy, r)))
                    : Number(static_cast<double>(get(copy, r)));
    };
    key.read = [get, range](const YAML::Node& n, int r, TeamConfig* c) {
        if constexpr (kInt) {
            get(*c, r) = static_cast<T>(
                InRange(static_cast<double>(Scalar<long long>(n, "an integer")), range));
        } else {
            get(*c, r) = static_cast<T>(InRange(Scalar<double>(n, "a number"), range));
        }
    };
    return key;
}

template <class G>
ConfigKey Flag(std::string path, G get, std::string doc, std::string kinds = "") {
    ConfigKey key{std::move(path),  "bool",  "true, false", std::move(doc),
                  std::move(kinds), nullptr, nullptr};
    key.show = [get](const TeamConfig& c, int r) {
        TeamConfig copy = c;
        return std::string(get(copy, r) ? "true" : "false");
    };
    key.read = [get](const YAML::Node& n, int r, TeamConfig* c) {
        get(*c, r) = Scalar<bool>(n, "true or false");
    };
    return key;
}

/// A string; a "path" is resolved against the configuration file's folder when relative.
template <class G>
ConfigKey Str(std::string path, G get, std::string doc, std::string kinds = "",
              bool is_path = false) {
    ConfigKey key{
        std::move(path), is_path ? "path" : "string", "", std::move(doc), std::move(kinds), nullptr,
        nullptr};
    key.show = [get](const TeamConfig& c, int r) {
        TeamConfig copy = c;
        return Quote(get(copy, r));
    };
    key.read = [get, is_path](const YAML::Node& n, int r, TeamConfig* c) {
        std::string value = Scalar<std::string>(n, "a string", true);
        if (is_path && !value.empty() && value.front() != '/') {
            value = (std::filesystem::path(c->path).parent_path() / value).string();
        }
        get(*c, r) = value;
    };
    return key;
}

template <class G>
ConfigKey FilePath(std::string path, G get, std::string doc, std::string kinds = "") {
    return Str(std::move(path), get, std::move(doc), std::move(kinds), true);
}

/// One of named values of an enum (or string) field.
template <class E, class G>
ConfigKey Choice(std::string path, G get, std::vector<std::pair<std::string, E>> names,
                 std::string doc, std::string kinds = "") {
    std::string range;
    for (const auto& [name, value] : names) range += (range.empty() ? "" : ", ") + name;
    ConfigKey key{std::move(path),  "choice", range,  std::move(doc),
                  std::move(kinds), nullptr,  nullptr};
    key.show = [get, names](const TeamConfig& c, int r) {
        TeamConfig copy = c;
        for (const auto& [name, value] : names) {
            if (get(copy, r) == value) return name;
        }
        return std::string("?");
    };
    key.read = [get, names, range](const YAML::Node& n, int r, TeamConfig* c) {
        const auto text = Scalar<std::string>(n, "one of " + range, true);
        for (const auto& [name, value] : names) {
            if (text == name) {
                get(*c, r) = value;
                return;
            }
        }
        throw std::invalid_argument("\"" + text + "\" is not one of " + range);
    };
    return key;
}

/// A list of exactly 3 finite numbers.
template <class G>
ConfigKey Vec3(std::string path, G get, std::string doc, std::string kinds) {
    ConfigKey key{std::move(path),  "list",  "3 numbers", std::move(doc),
                  std::move(kinds), nullptr, nullptr};
    key.show = [get](const TeamConfig& c, int r) {
        TeamConfig copy = c;
        const Eigen::Vector3d v = get(copy, r);
        return "[" + Number(v.x()) + ", " + Number(v.y()) + ", " + Number(v.z()) + "]";
    };
    key.read = [get](const YAML::Node& n, int r, TeamConfig* c) {
        if (!n.IsSequence() || n.size() != 3) throw std::invalid_argument("must be 3 numbers");
        for (int i = 0; i < 3; ++i) get(*c, r)[i] = InRange(Scalar<double>(n[i], "a number"), {});
    };
    return key;
}

ConfigKey RobotList() {
    ConfigKey key{"robots", "list",  "0, 1, ..., N-1", "the team: robot ids, ascending from 0",
                  "",       nullptr, nullptr};
    key.show = [](const TeamConfig& c, int) {
        std::string out;
        for (const int r : c.robots) out += (out.empty() ? "" : ", ") + std::to_string(r);
        return "[" + out + "]";
    };
    key.read = [](const YAML::Node& n, int, TeamConfig* c) {
        if (!n.IsSequence()) throw std::invalid_argument("must be a list of robot ids [0, 1, ...]");
        c->robots.clear();
        for (const auto& item : n) c->robots.push_back(Scalar<int>(item, "an integer"));
        if (c->robots.empty()) throw std::invalid_argument("must not be empty");
        for (size_t k = 0; k < c->robots.size(); ++k) {
            if (c->robots[k] != static_cast<int>(k)) {
                throw std::invalid_argument("must be 0, 1, ..., N-1");
            }
        }
    };
    return key;
}

}  // namespace

const std::vector<std::string>& SourceKindNames() {
    static const std::vector<std::string> names{"simulator", "keyframe_folder", "kitti",
                                                "split",     "rosbag",          "pose_graph"};
    return names;
}

namespace {

using actors::TeamMap;
using Kind = SourceConfig::Kind;
const Range positive{0.0, kInf, true};
const Range non_negative{0.0};

std::vector<ConfigKey> TopKeys() {
    return {
        RobotList(),
        Str(
            "log_dir", [](TeamConfig & c, int) -> auto& { return c.log_dir; },
            "durable per-robot logs here, replayed on start (empty: none)"),
        Choice<actors::StaleLogPolicy>(
            "log_stale", [](TeamConfig & c, int) -> auto& { return c.log_stale; },
            {{"refuse", actors::StaleLogPolicy::kRefuse},
             {"move_aside", actors::StaleLogPolicy::kMoveAside}},
            "a log of another mission or a corrupt one: refuse to start, or move it to "
            "FILE.stale-N and start afresh"),
    };
}

std::vector<ConfigKey> SourceKeys() {
    return {
        Choice<Kind>(
            "source.kind", [](TeamConfig & c, int) -> auto& { return c.source.kind; },
            {{"simulator", Kind::kSimulator},
             {"keyframe_folder", Kind::kKeyframeFolder},
             {"kitti", Kind::kKitti},
             {"split", Kind::kSplit},
             {"rosbag", Kind::kRosbag},
             {"pose_graph", Kind::kPoseGraph}},
            "where the keyframes come from"),
        Num<int>(
            "source.max_keyframes",
            [](TeamConfig & c, int) -> auto& { return c.source.max_keyframes; }, {0.0, 1e9},
            "keyframes per robot at most (0: all)"),
        Str(
            "source.scenario", [](TeamConfig & c, int) -> auto& { return c.source.scenario; },
            "named mission (city, tunnel-rendezvous, large-drift, swarm; \"\": defaults)",
            "simulator"),
        Num<std::uint64_t>(
            "source.seed", [](TeamConfig & c, int) -> auto& { return c.source.simulator.seed; },
            {0.0, 9.0e15}, "fixes the simulated world, drift and noise", "simulator"),
        Num<double>(
            "source.keyframe_spacing_m",
            [](TeamConfig & c, int) -> auto& { return c.source.simulator.keyframe_spacing_m; },
            {0.5, 100.0}, "travelled distance between simulated keyframes", "simulator"),
        FilePath(
            "source.paths.<robot>",
            [](TeamConfig & c, int r) -> auto& { return c.source.paths[r]; },
            "the robot's SC-LIO-SAM keyframe folder or ROS bag", "keyframe_folder rosbag"),
        Str(
            "source.cloud_topic",
            [](TeamConfig & c, int) -> auto& { return c.source.rosbag.cloud_topic; },
            "sensor_msgs/PointCloud2 topic of the bag", "rosbag"),
        Str(
            "source.odometry_topic",
            [](TeamConfig & c, int) -> auto& { return c.source.rosbag.odometry_topic; },
            "nav_msgs/Odometry topic of the bag", "rosbag"),
        Num<double>(
            "source.max_stamp_gap_s",
            [](TeamConfig & c, int) -> auto& { return c.source.rosbag.max_stamp_gap_s; },
            non_negative, "largest cloud-to-odometry stamp difference paired", "rosbag"),
        Choice<slam::RosbagCloudFrame>(
            "source.cloud_frame",
            [](TeamConfig & c, int) -> auto& { return c.source.rosbag.cloud_frame; },
            {{"auto", slam::RosbagCloudFrame::kAuto},
             {"sensor", slam::RosbagCloudFrame::kSensor},
             {"odom", slam::RosbagCloudFrame::kOdom}},
            "frame of the bag's clouds (auto: from the message header)", "rosbag"),
        Flag(
            "source.select_keyframes",
            [](TeamConfig & c, int) -> auto& { return c.source.select_keyframes; },
            "keep LIO-SAM's 1 m / 0.2 rad keyframes only (false: every scan)", "kitti"),
        FilePath(
            "source.sequences.<robot>.folder",
            [](TeamConfig & c, int r) -> auto& { return c.source.kitti[r].folder; },
            "the KITTI sequence folder (holds velodyne/)", "kitti"),
        FilePath(
            "source.sequences.<robot>.poses",
            [](TeamConfig & c, int r) -> auto& { return c.source.kitti[r].poses; },
            "KITTI poses file: odometry and ground truth", "kitti"),
        FilePath(
            "source.sequences.<robot>.calib",
            [](TeamConfig & c, int r) -> auto& { return c.source.kitti[r].calib; },
            "KITTI calibration file with a Tr: line", "kitti"),
    };
}

std::vector<ConfigKey> SplitSourceKeys() {
    return {
        FilePath(
            "source.path", [](TeamConfig & c, int) -> auto& { return c.source.split_path; },
            "the SC-LIO-SAM folder dealt out to the robots in turn", "split"),
        Num<int>(
            "source.robots", [](TeamConfig & c, int) -> auto& { return c.source.split_robots; },
            {0.0, 1e6}, "robots the folder is split into (0: the team's size)", "split"),
        Vec3(
            "source.offset.xyz_m",
            [](TeamConfig & c, int) -> auto& { return c.source.offset_xyz_m; },
            "robot r's odometry frame is the world moved by this offset r times", "split"),
        Vec3(
            "source.offset.rpy_deg",
            [](TeamConfig & c, int) -> auto& { return c.source.offset_rpy_deg; },
            "rotation of the offset: roll, pitch, yaw in degrees", "split"),
    };
}

std::vector<ConfigKey> PoseGraphSourceKeys() {
    return {
        FilePath(
            "source.graph", [](TeamConfig & c, int) -> auto& { return c.source.graph_path; },
            "the team's pose graph: a 3D g2o file or a dpgo CSV folder (robot<k>/)", "pose_graph"),
        Num<int>(
            "source.ranges.<robot>.begin",
            [](TeamConfig & c, int r) -> auto& { return c.source.ranges[r].first; }, non_negative,
            "first g2o vertex of the robot (all ranges zero: dpgo's contiguous split)",
            "pose_graph"),
        Num<int>(
            "source.ranges.<robot>.end",
            [](TeamConfig & c, int r) -> auto& { return c.source.ranges[r].second; }, non_negative,
            "one past the robot's last g2o vertex", "pose_graph"),
    };
}

std::vector<ConfigKey> SolverAndCertifierKeys() {
    return {
        // solver
        Num<int>(
            "solver.rank", [](TeamConfig & c, int) -> auto& { return c.node.solver.solver.rank; },
            {3.0, 64.0}, "rank r of the Stiefel relaxation (MATH.md)"),
        Num<double>(
            "solver.rel_grad_tol",
            [](TeamConfig & c, int) -> auto& { return c.node.solver.solver.rbcd.rel_grad_tol; },
            {0.0, 1.0, true, true}, "RBCD stops at ||grad|| <= this * max(1, f)"),
        Num<double>(
            "solver.odometry_sigma_t_m", [](TeamConfig & c, int) -> auto& {
                return c.node.solver.solver.noise.odometry_sigma_t_m;
            },
            positive, "odometry translation std per keyframe step"),
        Num<double>(
            "solver.odometry_sigma_r_rad", [](TeamConfig & c, int) -> auto& {
                return c.node.solver.solver.noise.odometry_sigma_r_rad;
            },
            positive, "odometry rotation std per keyframe step"),
        Num<int>(
            "solver.max_staircase_steps",
            [](TeamConfig & c, int) -> auto& { return c.node.certifier.max_staircase_steps; },
            {0.0, 20.0}, "rank increases of the Riemannian staircase at most"),
        // certifier
        Choice<bool>(
            "certifier.mode",
            [](TeamConfig & c, int) -> auto& { return c.node.certifier.distributed; },
            {{"distributed", true}, {"centralised", false}},
            "certify with the distributed Lanczos, or centralised at the anchor"),
        Num<int>(
            "certifier.max_krylov",
            [](TeamConfig & c, int) -> auto& { return c.node.certifier.lanczos.max_krylov; },
            {2.0, 10000.0}, "Lanczos iterations at most"),
        Num<double>(
            "certifier.tolerance",
            [](TeamConfig & c, int) -> auto& { return c.node.certifier.lanczos.tolerance; },
            positive, "Lanczos residual tolerance"),
    };
}

std::vector<ConfigKey> MatcherKeys() {
    return {
        // matcher
        Num<double>(
            "matcher.max_sc_distance",
            [](TeamConfig & c, int) -> auto& { return c.node.matcher.max_sc_distance; },
            {0.0, 1.0, true}, "Scan Context distance accepting a loop candidate"),
        Num<int>(
            "matcher.query_stride",
            [](TeamConfig & c, int) -> auto& { return c.node.matcher.query_stride; }, {1.0, 1e6},
            "only keyframes with index % stride == 0 query"),
        Num<int>(
            "matcher.min_intra_gap",
            [](TeamConfig & c, int) -> auto& { return c.node.matcher.min_intra_gap; }, {1.0, 1e6},
            "keyframes between the two ends of an intra-robot loop"),
        Flag(
            "matcher.intra_robot",
            [](TeamConfig & c, int) -> auto& { return c.node.matcher.intra_robot; },
            "also close loops within one robot"),
        Num<int>(
            "matcher.place_window",
            [](TeamConfig & c, int) -> auto& { return c.node.matcher.place_window; }, {0.0, 1e6},
            "neighbouring keyframes verified around a place match (0: one)"),
        Flag(
            "matcher.downsample_replies",
            [](TeamConfig & c, int) -> auto& { return c.node.matcher.downsample_replies; },
            "downsample cloud replies at registration.voxel_m"),
        Num<double>(
            "matcher.registration.voxel_m",
            [](TeamConfig & c, int) -> auto& { return c.node.matcher.registration.voxel_m; },
            {0.05, 10.0}, "fine GICP voxel size"),
        Num<double>(
            "matcher.registration.min_fitness",
            [](TeamConfig & c, int) -> auto& { return c.node.matcher.registration.min_fitness; },
            {0.0, 1.0}, "reject a registration below this inlier fraction"),
        Num<double>(
            "matcher.registration.max_correspondence_m", [](TeamConfig & c, int) -> auto& {
                return c.node.matcher.registration.max_correspondence_m;
            },
            positive, "fine GICP correspondence gate"),
    };
}

std::vector<ConfigKey> MappingAndNetworkKeys() {
    return {
        // mapping
        Flag(
            "mapping.enabled", [](TeamConfig & c, int) -> auto& { return c.node.mapping; },
            "run the TSDF mapper"),
        Num<double>(
            "mapping.voxel_m",
            [](TeamConfig & c, int) -> auto& { return c.node.mapper.map.tsdf.voxel_size_m; },
            {0.05, 5.0}, "TSDF voxel edge"),
        Num<double>(
            "mapping.memory_budget_mb",
            [](TeamConfig & c, int) -> auto& { return c.node.mapper.map.memory_budget_mb; },
            {0.0, 65536.0},
            "voxel memory of the map at most (0: none); over it new submaps get twice the "
            "voxel, up to 8x, then keyframes are skipped (counted in the report)"),
        Num<double>(
            "mapping.submap_distance_m",
            [](TeamConfig & c, int) -> auto& { return c.node.mapper.map.submap_distance_m; },
            positive, "a keyframe this far from the active submap starts a new one"),
        Flag(
            "mapping.share_submaps",
            [](TeamConfig & c, int) -> auto& { return c.node.mapper.share; },
            "send own submaps to the peers that ask"),
        Num<int>(
            "mapping.zstd_level",
            [](TeamConfig & c, int) -> auto& { return c.node.mapper.zstd_level; }, {0.0, 19.0},
            "zstd level of shared submaps"),
        Choice<TeamMap>(
            "mapping.team_map", [](TeamConfig & c, int) -> auto& { return c.node.mapper.team_map; },
            {{"anchor", TeamMap::kAnchor}, {"all", TeamMap::kAll}, {"none", TeamMap::kNone}},
            "which robots fuse their peers' submaps into a team map"),
        // network (robot mode)
        Str(
            "network.<robot>.host",
            [](TeamConfig & c, int r) -> auto& { return c.network[r].host; },
            "address peers connect to (\"*\" binds all interfaces)"),
        Num<int>(
            "network.<robot>.base_port",
            [](TeamConfig & c, int r) -> auto& { return c.network[r].base_port; }, {0.0, 65528.0},
            "edges on base_port + 1 .. + 7 (robot mode: > 0)"),
        FilePath(
            "network.<robot>.public_key",
            [](TeamConfig & c, int r) -> auto& { return c.network[r].public_key; },
            "PREFIX.pub of certislam keygen (empty: no CURVE)"),
        FilePath(
            "network.<robot>.secret_key",
            [](TeamConfig & c, int r) -> auto& { return c.network[r].secret_key; },
            "PREFIX.key, read by that robot only"),
    };
}

}  // namespace

const std::vector<ConfigKey>& TeamConfigKeys() {
    static const std::vector<ConfigKey> keys = [] {
        std::vector<ConfigKey> all;
        for (auto part : {TopKeys(), SourceKeys(), SplitSourceKeys(), PoseGraphSourceKeys(),
                          SolverAndCertifierKeys(), MatcherKeys(), MappingAndNetworkKeys()}) {
            for (auto& key : part) all.push_back(std::move(key));
        }
        return all;
    }();
    return keys;
}

}  // namespace certislam::bin
