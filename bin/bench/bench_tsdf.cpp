// `certislam bench tsdf`: TSDF integration time per KITTI HDL-64 scan at 0.1/0.2/0.5 m on one
// core, memory per voxel, compressed submap size, and re-anchoring time for 100/1000 submaps.
#include <sched.h>
#include <time.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "bin/command.h"
#include "slam/io/cloud_io.h"
#include "slam/mapping/submap.h"

namespace certislam::bin {
namespace {

// The build machine is shared (load ~10 on 2 cores): wall time counts other processes'
// slices, so the figures are this thread's CPU time (CLOCK_THREAD_CPUTIME_ID) on its one core.
struct Clock {
    using time_point = double;
    static double now() {
        timespec ts;
        clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
        return 1e3 * double(ts.tv_sec) + 1e-6 * double(ts.tv_nsec);
    }
};

double Ms(double t0_ms) { return Clock::now() - t0_ms; }

double Median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v.empty() ? 0.0 : v[v.size() / 2];
}

Eigen::Isometry3d FromRow(const std::vector<double>& r) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 4; ++j) T.matrix()(i, j) = r[4 * i + j];
    }
    return T;
}

// Velodyne poses of frames 94 and 95 (T_world_cam0 * Tr), or nullopt with a message.
std::optional<std::vector<Eigen::Isometry3d>> LoadPoses(const std::string& dir) {
    std::ifstream calib(dir + "calib_Tr_velo_to_cam0_seq00.txt"),
        poses(dir + "poses_cam0_subset.txt");
    std::string line;
    std::optional<Eigen::Isometry3d> Tr;
    std::map<int, Eigen::Isometry3d> cam;
    while (std::getline(calib, line)) {
        if (line.rfind("Tr:", 0) != 0) continue;
        std::istringstream in(line.substr(3));
        std::vector<double> r(12);
        for (double& v : r) in >> v;
        if (in) Tr = FromRow(r);
    }
    while (std::getline(poses, line)) {
        if (line.empty() || line[0] == '#') continue;
        std::istringstream in(line);
        int frame;
        std::vector<double> r(12);
        in >> frame;
        for (double& v : r) in >> v;
        if (in) cam[frame] = FromRow(r);
    }
    if (!Tr || !cam.count(94) || !cam.count(95)) return std::nullopt;
    return std::vector<Eigen::Isometry3d>{cam[94] * *Tr, cam[95] * *Tr};
}

struct IntegrationFigure {
    double ms_per_scan = 0, ms_per_scan_per_point_rays = 0, bytes_per_voxel = 0;
    double bytes_per_allocated_voxel = 0, submap_bytes_per_voxel = 0, mesh_ms = 0;
    std::size_t active_voxels = 0, memory_bytes = 0, submap_bytes = 0;
};

// Integrates scans 94 then 95 into a fresh volume `repeats` times; median time per Integrate.
IntegrationFigure TimeIntegration(const std::vector<slam::PointCloud>& scans,
                                  const std::vector<Eigen::Isometry3d>& poses, double voxel,
                                  int repeats) {
    IntegrationFigure f;
    for (bool grouped : {true, false}) {
        slam::TsdfConfig cfg;
        cfg.voxel_size_m = voxel;
        cfg.group_points_by_voxel = grouped;
        std::vector<double> ms;
        for (int r = 0; r < repeats; ++r) {
            slam::TsdfVolume volume(cfg);
            for (std::size_t i = 0; i < scans.size(); ++i) {
                const auto t0 = Clock::now();
                volume.Integrate(scans[i], poses[i]);
                ms.push_back(Ms(t0));
            }
            if (!grouped || r + 1 < repeats) continue;
            const slam::TsdfStats s = volume.Stats();
            f.active_voxels = s.active_voxels;
            f.memory_bytes = s.memory_bytes;
            f.bytes_per_voxel = double(s.memory_bytes) / double(s.active_voxels);
            f.bytes_per_allocated_voxel = double(s.memory_bytes) / double(s.allocated_voxels);
            f.submap_bytes = volume.Serialize().size();
            f.submap_bytes_per_voxel = double(f.submap_bytes) / double(s.active_voxels);
            const auto t0 = Clock::now();
            volume.ExtractMesh();
            f.mesh_ms = Ms(t0);
        }
        (grouped ? f.ms_per_scan : f.ms_per_scan_per_point_rays) = Median(ms);
    }
    return f;
}

// Builds `count` submaps (each a 1/50 subsample of scan 94 at 0.2 m) and times re-anchoring
// all of them to new poses, and the world mesh afterwards (cached submap meshes, moved).
std::pair<double, double> TimeReanchor(const slam::PointCloud& scan, int count, int repeats) {
    slam::PointCloud sparse;
    for (std::size_t i = 0; i < scan.size(); i += 50) sparse.push_back(scan[i]);
    slam::TsdfMapConfig cfg;
    cfg.submap_max_keyframes = 1;
    slam::TsdfMap map(0, cfg);
    std::vector<Eigen::Isometry3d> poses(static_cast<std::size_t>(count));
    for (int k = 0; k < count; ++k) {
        poses[k] = Eigen::Translation3d(2.0 * k, 0.0, 0.0) * Eigen::Isometry3d::Identity();
        map.Insert(k, poses[k], sparse);
    }
    map.ExtractMesh();  // fills the per-submap caches
    std::vector<double> ms;
    for (int r = 0; r < repeats; ++r) {
        const Eigen::Isometry3d correction(
            Eigen::AngleAxisd(0.01 * (r + 1), Eigen::Vector3d::UnitZ()));
        const auto t0 = Clock::now();
        map.Reanchor([&](const slam::PoseId& id) -> std::optional<Eigen::Isometry3d> {
            return correction * poses[static_cast<std::size_t>(id.index)];
        });
        ms.push_back(Ms(t0));
    }
    const auto t0 = Clock::now();
    map.ExtractMesh();
    return {Median(ms), Ms(t0)};
}

int RunTsdfBench(int argc, char** argv) {
    CLI::App app{"TSDF integration per KITTI scan (one core), memory per voxel, re-anchoring"};
    bool json = false;
    std::string data = "../shared/data";  // from the repository root, as in the tests
    int repeats = 5;
    app.add_flag("--json", json, "machine-readable output");
    app.add_option("--data", data, "the shared data folder (holds lidar/)");
    app.add_option("--repeats", repeats, "timed repetitions")->check(CLI::PositiveNumber);
    CLI11_PARSE(app, argc, argv);

    cpu_set_t one;  // the figure is for one core: pin before anything runs
    CPU_ZERO(&one);
    CPU_SET(sched_getcpu(), &one);
    sched_setaffinity(0, sizeof one, &one);

    const std::string dir = data + "/lidar/kitti00_scancontext_samples/";
    std::vector<slam::PointCloud> scans;
    for (const char* f : {"000094.bin", "000095.bin"}) {
        slam::CloudReadResult r = slam::ReadKittiBin(dir + "velodyne/" + f);
        if (!r.ok()) {
            std::fprintf(stderr, "certislam bench tsdf: %s\n", r.error.c_str());
            return 1;
        }
        scans.push_back(std::move(r.cloud));
    }
    const auto poses = LoadPoses(dir);
    if (!poses) {
        std::fprintf(stderr, "certislam bench tsdf: cannot read the poses/calibration in %s\n",
                     dir.c_str());
        return 1;
    }
    nlohmann::json out{{"points", scans[0].size()},
                       {"integration", nlohmann::json::array()},
                       {"reanchor", nlohmann::json::array()}};
    for (double voxel : {0.1, 0.2, 0.5}) {
        const IntegrationFigure f = TimeIntegration(scans, *poses, voxel, repeats);
        out["integration"].push_back({{"voxel_m", voxel},
                                      {"ms_per_scan", f.ms_per_scan},
                                      {"ms_per_scan_per_point_rays", f.ms_per_scan_per_point_rays},
                                      {"points", scans[0].size()},
                                      {"active_voxels", f.active_voxels},
                                      {"memory_bytes", f.memory_bytes},
                                      {"bytes_per_voxel", f.bytes_per_voxel},
                                      {"bytes_per_allocated_voxel", f.bytes_per_allocated_voxel},
                                      {"submap_bytes", f.submap_bytes},
                                      {"submap_bytes_per_voxel", f.submap_bytes_per_voxel},
                                      {"mesh_ms", f.mesh_ms}});
    }
    for (int count : {100, 1000}) {
        const auto [reanchor_ms, mesh_ms] = TimeReanchor(scans[0], count, repeats);
        out["reanchor"].push_back(
            {{"submaps", count}, {"reanchor_ms", reanchor_ms}, {"world_mesh_ms", mesh_ms}});
    }
    if (json) {
        std::printf("%s\n", out.dump().c_str());
        return 0;
    }
    std::printf("KITTI 00 scans 94+95 (%zu points), one core, thread CPU time, median of %d:\n",
                scans[0].size(), repeats);
    for (const auto& f : out["integration"]) {
        std::printf(
            "  %.1f m: %6.1f ms/scan (per-point rays %6.1f), %zu voxels, %.1f B/voxel "
            "(%.1f per allocated), submap %.2f B/voxel compressed, mesh %.1f ms\n",
            f["voxel_m"].get<double>(), f["ms_per_scan"].get<double>(),
            f["ms_per_scan_per_point_rays"].get<double>(), f["active_voxels"].get<std::size_t>(),
            f["bytes_per_voxel"].get<double>(), f["bytes_per_allocated_voxel"].get<double>(),
            f["submap_bytes_per_voxel"].get<double>(), f["mesh_ms"].get<double>());
    }
    for (const auto& r : out["reanchor"]) {
        std::printf("  re-anchor %4d submaps: %.4f ms (world mesh after: %.1f ms)\n",
                    r["submaps"].get<int>(), r["reanchor_ms"].get<double>(),
                    r["world_mesh_ms"].get<double>());
    }
    return 0;
}

const BenchRegistrar kBench{"tsdf", "TSDF integration per KITTI scan, memory, re-anchoring",
                            RunTsdfBench};

}  // namespace
}  // namespace certislam::bin
