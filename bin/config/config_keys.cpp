// The team-configuration keys: each bound to its field of TeamConfig, with type, range and doc.
#include "bin/config/config_keys.h"

#include <string>
#include <utility>
#include <vector>

#include "bin/config/config_key_kinds.h"
#include "bin/config/team_config.h"

namespace certislam::bin {
using config_key_kinds::Choice;
using config_key_kinds::FilePath;
using config_key_kinds::Flag;
using config_key_kinds::kInf;
using config_key_kinds::Num;
using config_key_kinds::Range;
using config_key_kinds::RobotList;
using config_key_kinds::Str;
using config_key_kinds::Vec3;

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
        Num<double>(
            "quiet_s", [](TeamConfig & c, int) -> auto& { return c.quiet_s; }, {0.0, 3600.0},
            "a robot is done once certified and unchanged this long"),
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
            "named mission (city, tunnel-rendezvous, large-drift, swarm; \"\": defaults): its "
            "routes, drift and keyframe spacing (over source.keyframe_spacing_m); "
            "matcher.query_stride stays the config's",
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
            "sensor_msgs/PointCloud2 topic of the bag ({robot}: the robot's id)", "rosbag"),
        Str(
            "source.odometry_topic",
            [](TeamConfig & c, int) -> auto& { return c.source.rosbag.odometry_topic; },
            "nav_msgs/Odometry topic of the bag ({robot}: the robot's id)", "rosbag"),
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
            "the team's pose graph: a g2o file (a planar one lifted to SE(3)) or a dpgo CSV folder "
            "(robot<k>/)",
            "pose_graph"),
        Num<int>(
            "source.ranges.<robot>.begin",
            [](TeamConfig & c, int r) -> auto& { return c.source.ranges[r].first; }, non_negative,
            "first vertex of the robot, in file order (a folder: its robots one after another; "
            "all ranges zero: dpgo's contiguous split)",
            "pose_graph"),
        Num<int>(
            "source.ranges.<robot>.end",
            [](TeamConfig & c, int r) -> auto& { return c.source.ranges[r].second; }, non_negative,
            "one past the robot's last vertex", "pose_graph"),
    };
}

std::vector<ConfigKey> SolverKeys() {
    return {
        // solver
        Num<int>(
            "solver.rank", [](TeamConfig & c, int) -> auto& { return c.node.solver.solver.rank; },
            {3.0, 64.0}, "rank r of the Stiefel relaxation (MATH.md)"),
        Num<double>(
            "solver.rel_grad_tol",
            [](TeamConfig & c, int) -> auto& { return c.node.solver.solver.rbcd.rel_grad_tol; },
            {0.0, 1.0, true, true}, "RBCD stops at ||grad|| <= this * max(1, f)"),
        Choice<bool>(
            "solver.mode", [](TeamConfig & c, int) -> auto& { return c.node.solver.synchronous; },
            {{"rounds", true}, {"asynchronous", false}},
            "keyframe sources: asynchronous RBCD throughout, or asynchronous while the graph "
            "grows and synchronous RBCD++ rounds once it is final (rounds; a restarted robot's "
            "peers rejoin it in a new round session); pose graphs: rounds"),
        Num<double>(
            "solver.rounds_rel_grad_tol",
            [](TeamConfig & c, int) -> auto& { return c.node.solver.rounds.rel_grad_tol; },
            {0.0, 1.0, true, true},
            "solver.mode rounds on a keyframe source: the rounds stop at ||grad|| <= this * "
            "max(1, f) (pose graphs: solve --distributed's)"),
        Num<int>(
            "solver.rounds_overlap",
            [](TeamConfig & c, int) -> auto& { return c.node.solver.rounds.overlap_depth; },
            {0.0, 16.0},
            "solver.mode rounds: a robot's sweep also moves the poses of later-sweeping neighbours "
            "within this many edges of its own, and they go on from there (overlapping blocks; 0: "
            "own poses only); one value per team: round poses of another are dropped (counted)"),
        Num<int>(
            "solver.finish_after_rounds",
            [](TeamConfig & c, int) -> auto& { return c.node.solver.finish_after_rounds; },
            {0.0, 1e6},
            "solver.mode rounds: from this round on, rounds whose rate over the last 20 projects "
            "their tolerance beyond 4 solver.rounds_max, and rounds that reach it, hand the team "
            "to "
            "its second-order finish (a distributed trust region on the whole X: neighbour "
            "exchanges and sums only); 0: none (asynchronous updates after solver.rounds_max)"),
        Num<int>(
            "solver.rounds_max",
            [](TeamConfig & c, int) -> auto& { return c.node.solver.rounds.max_rounds; },
            {1.0, 1e6},
            "solver.mode rounds: rounds at most, then the finish (or asynchronous updates)"),
        Num<int>(
            "solver.finish_overlap",
            [](TeamConfig & c, int) -> auto& { return c.node.solver.finish.overlap; }, {0.0, 8.0},
            "the finish's Schwarz domains: the own poses and the neighbours' within this many "
            "edges (0: block Jacobi)"),
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
    };
}

std::vector<ConfigKey> CertifierKeys() {
    return {
        Choice<bool>(
            "certifier.mode",
            [](TeamConfig & c, int) -> auto& { return c.node.certifier.distributed; },
            {{"distributed", true}, {"centralised", false}},
            "certify with the distributed eigen-solve, or centralised at the anchor"),
        Choice<certify::LanczosSettings::Method>(
            "certifier.eigensolver",
            [](TeamConfig & c, int) -> auto& { return c.node.certifier.lanczos.method; },
            {{"lanczos", certify::LanczosSettings::Method::kLanczos},
             {"lobpcg", certify::LanczosSettings::Method::kLobpcg}},
            "distributed eigen-solver: Lanczos, or block-Jacobi preconditioned LOBPCG"),
        Num<int>(
            "certifier.lobpcg_block",
            [](TeamConfig & c, int) -> auto& { return c.node.certifier.lanczos.lobpcg.block_size; },
            {1.0, 16.0}, "LOBPCG block size"),
        Num<int>(
            "certifier.max_krylov",
            [](TeamConfig & c, int) -> auto& { return c.node.certifier.lanczos.max_krylov; },
            {2.0, 10000.0}, "Lanczos iterations at most"),
        Num<double>(
            "certifier.tolerance",
            [](TeamConfig & c, int) -> auto& { return c.node.certifier.lanczos.tolerance; },
            positive, "Lanczos residual tolerance"),
        Num<double>(
            "certifier.max_relative_bound", [](TeamConfig & c, int) -> auto& {
                return c.node.certifier.certificate.max_relative_bound;
            },
            {0.0, 1.0, true, true},
            "certified needs (f(X) - lower bound) / f(X) at most this (MATH.md)"),
        Num<double>(
            "certifier.eta_relative",
            [](TeamConfig & c, int) -> auto& { return c.node.certifier.certificate.eta_relative; },
            {0.0, 1.0, true, true},
            "eta = this times the norm of Q; S + eta D must be PSD (MATH.md)"),
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
        Num<int>(
            "matcher.max_candidates_per_query",
            [](TeamConfig & c, int) -> auto& { return c.node.matcher.max_candidates_per_query; },
            {0.0, 1e6}, "best Scan Context candidates registered per keyframe and robot (0: all)"),
        Num<int>(
            "matcher.registration_threads",
            [](TeamConfig & c, int) -> auto& { return c.node.matcher.registration_threads; },
            {1.0, 64.0},
            "threads registering loop candidates (verdicts applied in candidate order)"),
        Flag(
            "matcher.downsample_replies",
            [](TeamConfig & c, int) -> auto& { return c.node.matcher.downsample_replies; },
            "keep own keyframe clouds and send cloud replies downsampled at registration.voxel_m"),
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
        Num<int>(
            "mapping.mesh_threads",
            [](TeamConfig & c, int) -> auto& { return c.node.mapper.mesh_threads; }, {1.0, 64.0},
            "threads fusing and meshing the team map"),
        Choice<int>(
            "mapping.share_sdf",
            [](TeamConfig & c, int) -> auto& { return c.node.mapper.share_sdf_bits; },
            {{"int16", 16}, {"int8", 8}, {"lossless", 32}},
            "distances of shared submaps: quantised to 16 or 8 bits (weights to 8), or lossless "
            "floats"),
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
        Str(
            "network.<robot>.ipc_dir",
            [](TeamConfig & c, int r) -> auto& { return c.network[r].ipc_dir; },
            "robots of one host: edges are Unix sockets in this folder, not tcp (no CURVE; "
            "the folder's permissions guard them)"),
    };
}

}  // namespace

const std::vector<ConfigKey>& TeamConfigKeys() {
    static const std::vector<ConfigKey> keys = [] {
        std::vector<ConfigKey> all;
        for (auto part : {TopKeys(), SourceKeys(), SplitSourceKeys(), PoseGraphSourceKeys(),
                          SolverKeys(), CertifierKeys(), MatcherKeys(), MappingAndNetworkKeys()}) {
            for (auto& key : part) all.push_back(std::move(key));
        }
        return all;
    }();
    return keys;
}

}  // namespace certislam::bin
