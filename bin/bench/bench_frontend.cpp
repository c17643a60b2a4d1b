// `certislam bench frontend`: Scan Context descriptor time per KITTI scan, retrieval against
// 10,000 stored descriptors, registration time per pair, and descriptor vs cloud bytes.
#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "bin/bench/bench_frontend_bandwidth.h"
#include "bin/command.h"
#include "slam/frontend/descriptor_database.h"
#include "slam/frontend/downsample.h"
#include "slam/frontend/registration.h"
#include "slam/frontend/scan_context.h"
#include "slam/frontend/scan_context_compression.h"
#include "slam/io/cloud_io.h"

namespace certislam::bin {
namespace {

using Clock = std::chrono::steady_clock;

double Ms(Clock::time_point start) {
    return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

// CPU time of the process, all threads (ms): on a shared machine wall time includes other
// processes' turns.
double CpuMs() {
    timespec t{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return 1e3 * static_cast<double>(t.tv_sec) + 1e-6 * static_cast<double>(t.tv_nsec);
}

slam::PointCloud Load(const std::string& path) {
    slam::CloudReadResult r = slam::ReadCloud(path);
    if (!r.ok()) throw std::runtime_error(r.error);
    return std::move(r.cloud);
}

// A stored descriptor derived from a real one: random column shift and 5 % multiplicative bin
// noise, so the 10,000 entries are distinct but have real descriptors' statistics.
slam::ScanContext Perturbed(const slam::ScanContext& base, std::mt19937& rng) {
    std::uniform_int_distribution<int> shift(0, static_cast<int>(base.bins.cols()) - 1);
    std::normal_distribution<float> noise(1.0f, 0.05f);
    const int s = shift(rng);
    slam::ScanContext out = base;
    for (int i = 0; i < base.bins.rows(); ++i) {
        for (int j = 0; j < base.bins.cols(); ++j) {
            out.bins(i, (j + s) % base.bins.cols()) = base.bins(i, j) * noise(rng);
        }
    }
    out.ring_key = out.bins.rowwise().mean();
    out.sector_key = out.bins.colwise().mean().transpose();
    return out;
}

struct PairTiming {
    std::string name;
    double ms = 0.0;
    double cpu_ms = 0.0;
    bool accepted = false;
};

PairTiming TimePair(const std::string& name, const slam::PointCloud& source,
                    const slam::PointCloud& target, const slam::RegistrationConfig& config,
                    int repeats) {
    const slam::ScanContextConfig sc;
    const auto m = slam::ScanContextDistance(slam::MakeScanContext(source, sc),
                                             slam::MakeScanContext(target, sc));
    PairTiming t{name};
    const auto start = Clock::now();
    const double cpu = CpuMs();
    for (int k = 0; k < repeats; ++k) {
        t.accepted =
            slam::RegisterScans(source, target, slam::YawGuess(m.yaw_rad), config).accepted();
    }
    t.cpu_ms = (CpuMs() - cpu) / repeats;
    t.ms = Ms(start) / repeats;
    return t;
}

/// Every figure the bench reports.
struct FrontendFigures {
    std::size_t scan_points = 0;
    double descriptor_ms = 0.0, descriptor_cpu_ms = 0.0;
    int stored = 0;
    double insert_ms = 0.0, retrieval_ms = 0.0, retrieval_cpu_ms = 0.0;
    std::size_t found = 0;
    std::vector<PairTiming> pairs;
    double descriptor_bytes = 0.0, cloud_bytes = 0.0, compact_bytes = 0.0;
    std::vector<BandwidthFigures> missions;
};

// 1. Descriptor time per KITTI scan (raw ~122k points, no voxel, as the paper); returns the
// descriptors, with those of the KAIST03 keyframes found under `lidar` appended.
std::vector<slam::ScanContext> TimeDescriptors(const std::vector<slam::PointCloud>& scans,
                                               const std::string& lidar, int repeats,
                                               FrontendFigures* f) {
    const slam::ScanContextConfig sc;
    const auto start = Clock::now();
    const double cpu = CpuMs();
    std::vector<slam::ScanContext> bases;
    bases.reserve(static_cast<std::size_t>(repeats) + 21);
    for (int k = 0; k < repeats; ++k) {
        bases.push_back(slam::MakeScanContext(scans[k % scans.size()], sc));
    }
    f->descriptor_ms = Ms(start) / repeats;
    f->descriptor_cpu_ms = (CpuMs() - cpu) / repeats;
    for (int k = 0; k < 21; ++k) {
        char name[64];
        std::snprintf(name, sizeof name, "mulran_kaist03_keyframes/Scans/%06d.pcd", k);
        if (std::filesystem::exists(lidar + name)) {
            bases.push_back(slam::MakeScanContext(Load(lidar + name), sc));
        }
    }
    return bases;
}

// 2. Retrieval against `stored` descriptors (growing k-d tree + SC re-ranking of 10).
void TimeRetrieval(const std::vector<slam::ScanContext>& bases, int stored, int queries,
                   FrontendFigures* f) {
    std::mt19937 rng(1);
    slam::DescriptorDatabase db;
    auto start = Clock::now();
    for (int k = 0; k < stored; ++k) db.Add({1, k}, Perturbed(bases[k % bases.size()], rng));
    f->stored = stored;
    f->insert_ms = Ms(start) / stored;
    std::vector<slam::ScanContext> query_descriptors;
    query_descriptors.reserve(static_cast<std::size_t>(queries));
    for (int q = 0; q < queries; ++q) {
        query_descriptors.push_back(Perturbed(bases[q % bases.size()], rng));
    }
    start = Clock::now();
    const double cpu = CpuMs();
    for (int q = 0; q < queries; ++q) f->found += db.Query({0, q}, query_descriptors[q]).size();
    f->retrieval_ms = Ms(start) / queries;
    f->retrieval_cpu_ms = (CpuMs() - cpu) / queries;
}

// 3. Registration per pair.
std::vector<PairTiming> TimeRegistration(const std::vector<slam::PointCloud>& scans,
                                         const std::string& lidar, int repeats) {
    std::vector<PairTiming> pairs;
    slam::RegistrationConfig fine;  // 0.2 m voxels, coarse 1 m stage
    pairs.push_back(TimePair("kitti00 94->95 (0.2 m voxel)", scans[1], scans[0], fine, repeats));
    pairs.push_back(TimePair("hdl_pair_fast_gicp (0.2 m voxel)",
                             Load(lidar + "hdl_pair_fast_gicp/251371071.pcd"),
                             Load(lidar + "hdl_pair_fast_gicp/251370668.pcd"), fine, repeats));
    slam::RegistrationConfig mission = fine;  // the mission loop stage's settings
    mission.voxel_m = 0.4;
    mission.max_correspondence_m = 1.0;
    pairs.push_back(
        TimePair("kitti00 94->95 (0.4 m voxel, mission)", scans[1], scans[0], mission, repeats));
    return pairs;
}

// 4. Bandwidth: descriptor bytes vs the 0.2 m downsampled cloud (float32 xyz).
void MeasureBytes(const slam::ScanContext& descriptor, const std::vector<slam::PointCloud>& scans,
                  FrontendFigures* f) {
    f->descriptor_bytes = static_cast<double>(slam::SerializeScanContext(descriptor).size());
    for (const auto& s : scans) f->cloud_bytes += 12.0 * slam::VoxelDownsample(s, 0.2).size();
    f->cloud_bytes /= static_cast<double>(scans.size());
    f->compact_bytes = static_cast<double>(slam::EncodeScanContextCompact(descriptor).size());
}

void PrintJson(const FrontendFigures& f) {
    nlohmann::json j{{"descriptor_ms_per_kitti_scan", f.descriptor_ms},
                     {"descriptor_cpu_ms_per_kitti_scan", f.descriptor_cpu_ms},
                     {"retrieval_cpu_ms_per_query", f.retrieval_cpu_ms},
                     {"stored_descriptors", f.stored},
                     {"insert_ms_per_descriptor", f.insert_ms},
                     {"retrieval_ms_per_query", f.retrieval_ms},
                     {"retrieval_candidates_found", f.found},
                     {"descriptor_bytes", f.descriptor_bytes},
                     {"downsampled_cloud_bytes_0_2m", f.cloud_bytes},
                     {"bandwidth_ratio", f.cloud_bytes / f.descriptor_bytes},
                     {"descriptor_compact_bytes", f.compact_bytes},
                     {"bandwidth_ratio_compact", f.cloud_bytes / f.compact_bytes}};
    for (const auto& m : f.missions) j["missions"].push_back(m.ToJson());
    for (const auto& p : f.pairs) {
        j["registration"].push_back(
            {{"pair", p.name}, {"ms", p.ms}, {"cpu_ms", p.cpu_ms}, {"accepted", p.accepted}});
    }
    std::printf("%s\n", j.dump(2).c_str());
}

void PrintText(const FrontendFigures& f) {
    std::printf("descriptor: %.3f ms wall, %.3f ms CPU per KITTI scan (%zu points)\n",
                f.descriptor_ms, f.descriptor_cpu_ms, f.scan_points);
    std::printf(
        "retrieval: %.3f ms wall, %.3f ms CPU per query against %d stored (insert %.4f ms)\n",
        f.retrieval_ms, f.retrieval_cpu_ms, f.stored, f.insert_ms);
    for (const auto& p : f.pairs) {
        std::printf("registration: %.1f ms wall, %.1f ms CPU  %s%s\n", p.ms, p.cpu_ms,
                    p.name.c_str(), p.accepted ? "" : " (NOT accepted)");
    }
    std::printf("bandwidth: descriptor %.0f B vs 0.2 m downsampled cloud %.0f B: %.1fx less\n",
                f.descriptor_bytes, f.cloud_bytes, f.cloud_bytes / f.descriptor_bytes);
    std::printf("bandwidth: compact descriptor %.0f B: %.1fx less than that cloud\n",
                f.compact_bytes, f.cloud_bytes / f.compact_bytes);
    for (const auto& m : f.missions) std::printf("mission: %s\n", m.ToJson().dump().c_str());
}

int RunFrontendBench(int argc, char** argv) {
    CLI::App app{"Front-end timings: descriptor, retrieval, registration; bandwidth"};
    bool json = false;
    int stored = 10000, queries = 200, descriptor_repeats = 50, pair_repeats = 3;
    std::string data = "../shared/data";  // from the repository root, as in the tests
    app.add_flag("--json", json, "machine-readable output");
    app.add_option("--data", data, "the shared data folder (holds lidar/)");
    app.add_option("--stored", stored, "descriptors in the database")->check(CLI::PositiveNumber);
    app.add_option("--queries", queries, "retrieval queries")->check(CLI::PositiveNumber);
    bool skip_missions = false;
    app.add_flag("--skip-missions", skip_missions,
                 "skip the loop-stage bytes on the simulated mission and KAIST03 (~1 min)");
    CLI11_PARSE(app, argc, argv);
    const std::string lidar = data + "/lidar/";
    const std::string kitti = lidar + "kitti00_scancontext_samples/velodyne/";
    std::vector<slam::PointCloud> scans;
    for (const char* f : {"000094.bin", "000095.bin", "000198.bin", "000199.bin"}) {
        scans.push_back(Load(kitti + f));
    }
    FrontendFigures f;
    f.scan_points = scans[0].size();
    const std::vector<slam::ScanContext> bases =
        TimeDescriptors(scans, lidar, descriptor_repeats, &f);
    TimeRetrieval(bases, stored, queries, &f);
    f.pairs = TimeRegistration(scans, lidar, pair_repeats);
    MeasureBytes(bases[0], scans, &f);
    // 5. Loop-stage bytes per keyframe on whole missions (compression + cloud-request gate).
    if (!skip_missions) f.missions = MeasureMissionBandwidth(lidar + "mulran_kaist03_keyframes");
    if (json) {
        PrintJson(f);
    } else {
        PrintText(f);
    }
    return 0;
}

const BenchRegistrar kBench{"frontend",
                            "Scan Context descriptor/retrieval, registration per pair, bandwidth",
                            RunFrontendBench};

}  // namespace
}  // namespace certislam::bin
