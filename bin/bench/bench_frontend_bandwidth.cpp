// Loop-stage bandwidth: compact descriptors, encoded candidate clouds, one request per place.
#include "bin/bench/bench_frontend_bandwidth.h"

#include <chrono>
#include <cmath>
#include <stdexcept>

#include "slam/frontend/cloud_request_gate.h"
#include "slam/frontend/downsample.h"
#include "slam/frontend/loop_detection.h"
#include "slam/frontend/loop_verification.h"
#include "slam/frontend/scan_context_compression.h"
#include "slam/io/cloud_compression.h"
#include "slam/io/keyframe_sources_io.h"
#include "slam/sim/simulator.h"

namespace certislam::bin {
namespace {

constexpr double kTrueLoopMaxTranslationM = 0.5;  // as test_slam_frontend_loop_verification
constexpr double kTrueLoopMaxRotationRad = 2.0 * M_PI / 180.0;

bool AgreesWithTruth(const slam::LoopClosure& loop,
                     const std::vector<std::vector<Eigen::Isometry3d>>& truth) {
    const Eigen::Isometry3d T_true =
        truth[loop.a.robot][loop.a.index].inverse() * truth[loop.b.robot][loop.b.index];
    const Eigen::Isometry3d E = T_true.inverse() * loop.T_a_b;
    return E.translation().norm() < kTrueLoopMaxTranslationM &&
           Eigen::AngleAxisd(E.rotation()).angle() < kTrueLoopMaxRotationRad;
}

// Every keyframe's cloud as a peer receives it: downsampled to the voxel, encoded, decoded.
std::vector<std::vector<slam::Keyframe>> AsReceived(
    const std::vector<std::vector<slam::Keyframe>>& robots, double voxel_m,
    std::vector<std::vector<double>>* encoded_bytes) {
    auto received = robots;
    encoded_bytes->assign(robots.size(), {});
    for (auto& keyframes : received) {
        for (auto& kf : keyframes) {
            const auto bytes = slam::EncodeCloud(slam::VoxelDownsample(*kf.cloud, voxel_m)).bytes;
            (*encoded_bytes)[kf.robot].push_back(static_cast<double>(bytes.size()));
            kf.cloud = std::make_shared<const slam::PointCloud>(slam::DecodeCloud(bytes).cloud);
        }
    }
    return received;
}

// Verifies the candidates in order through a cloud-request gate, each inter-robot match cloud
// as received (downsampled, encoded, decoded), then PCM; loops checked against the truth.
GatedFigures VerifyThrough(const std::vector<std::vector<slam::Keyframe>>& robots,
                           const std::vector<std::vector<slam::Keyframe>>& received,
                           const std::vector<std::vector<double>>& encoded,
                           const std::vector<slam::LoopCandidate>& candidates,
                           const std::vector<std::vector<Eigen::Isometry3d>>& truth,
                           const slam::LoopDetectionConfig& config,
                           const slam::CloudRequestGateConfig& gate_config) {
    GatedFigures g;
    g.place_window = gate_config.place_window;
    slam::CloudRequestGate gate(gate_config);
    std::vector<slam::VerifiedLoop> verified;
    slam::LoopDetectionStats stats;
    for (const auto& c : candidates) {
        const auto decision = gate.Admit(c);
        if (decision == slam::CloudRequestGate::Decision::kSkip) continue;
        if (decision == slam::CloudRequestGate::Decision::kFetch) {
            ++g.fetches;
            g.clouds_encoded += encoded[c.match.robot][c.match.index];
        }
        auto pair = robots;  // the query's own cloud; the match's as received when inter-robot
        if (c.query.robot != c.match.robot) {
            pair[c.match.robot][c.match.index] = received[c.match.robot][c.match.index];
        }
        auto v = slam::VerifyCandidates(pair, {c}, config, &stats);
        if (v.empty()) gate.Failed(c);
        verified.insert(verified.end(), v.begin(), v.end());
    }
    for (const auto& loop : slam::RejectOutliers(robots, verified, config, &stats)) {
        ++g.loops;
        g.inter_loops += loop.inter_robot();
        g.wrong_loops += !AgreesWithTruth(loop, truth);
    }
    return g;
}

// Measures `robots` (truth per robot and keyframe in one world frame, for the precision).
BandwidthFigures MeasureBandwidth(const std::string& name,
                                  const std::vector<std::vector<slam::Keyframe>>& robots,
                                  const std::vector<std::vector<Eigen::Isometry3d>>& truth,
                                  const slam::LoopDetectionConfig& config) {
    const auto start = std::chrono::steady_clock::now();
    BandwidthFigures f;
    f.mission = name;
    const double peers = static_cast<double>(robots.size()) - 1.0;
    std::vector<std::vector<slam::ScanContext>> descriptors(robots.size());
    for (size_t r = 0; r < robots.size(); ++r) {
        for (const auto& kf : robots[r]) {
            descriptors[r].push_back(slam::MakeScanContext(*kf.cloud, config.scan_context));
            f.descriptor_float += peers * slam::SerializeScanContext(descriptors[r].back()).size();
            f.descriptor_compact +=
                peers * slam::EncodeScanContextCompact(descriptors[r].back()).size();
            f.baseline_cloud += 12.0 * slam::VoxelDownsample(*kf.cloud, config.voxel_m).size();
            f.baseline_cloud_0_2m += 12.0 * slam::VoxelDownsample(*kf.cloud, 0.2).size();
            ++f.keyframes;
        }
    }
    std::vector<std::vector<double>> encoded;
    const auto received = AsReceived(robots, config.voxel_m, &encoded);
    const auto candidates = slam::DetectCandidates(descriptors, robots, config);
    for (const auto& c : candidates) {
        if (c.query.robot == c.match.robot) continue;
        ++f.inter_candidates;
        f.clouds_float_all += 12.0 * received[c.match.robot][c.match.index].cloud->size();
        f.clouds_encoded_all += encoded[c.match.robot][c.match.index];
    }
    for (const int window : {0, 3, 10}) {
        slam::CloudRequestGateConfig gate;
        gate.max_sc_distance = config.max_sc_distance;
        gate.place_window = window;
        f.gated.push_back(
            VerifyThrough(robots, received, encoded, candidates, truth, config, gate));
        f.gated.back().clouds_encoded /= static_cast<double>(f.keyframes);
    }
    for (double* v : {&f.descriptor_float, &f.descriptor_compact, &f.clouds_float_all,
                      &f.clouds_encoded_all, &f.baseline_cloud, &f.baseline_cloud_0_2m}) {
        *v /= static_cast<double>(f.keyframes);
    }
    f.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return f;
}

}  // namespace

nlohmann::json BandwidthFigures::ToJson() const {
    nlohmann::json j{{"mission", mission},
                     {"keyframes", keyframes},
                     {"inter_robot_candidates", inter_candidates},
                     {"baseline_cloud_bytes_at_voxel", baseline_cloud},
                     {"baseline_cloud_bytes_0_2m", baseline_cloud_0_2m},
                     {"per_keyframe_bytes",
                      {{"descriptor_float32", descriptor_float},
                       {"descriptor_compact", descriptor_compact},
                       {"candidate_clouds_float32_all", clouds_float_all},
                       {"candidate_clouds_encoded_all", clouds_encoded_all}}},
                     {"old_total", descriptor_float + clouds_float_all},
                     {"ratio_old", baseline_cloud / (descriptor_float + clouds_float_all)},
                     {"seconds", seconds}};
    for (const auto& g : gated) {
        const double total = descriptor_compact + g.clouds_encoded;
        j["gated"].push_back({{"place_window", g.place_window},
                              {"cloud_fetches", g.fetches},
                              {"clouds_encoded_per_keyframe", g.clouds_encoded},
                              {"total_per_keyframe", total},
                              {"ratio", baseline_cloud / total},
                              {"ratio_vs_0_2m_cloud", baseline_cloud_0_2m / total},
                              {"loops", g.loops},
                              {"inter_robot_loops", g.inter_loops},
                              {"wrong_loops", g.wrong_loops}});
    }
    return j;
}

std::vector<BandwidthFigures> MeasureMissionBandwidth(const std::string& kaist_folder) {
    std::vector<BandwidthFigures> out;
    const slam::SimulatedMission mission = slam::SimulateMission(slam::SimulatorConfig{});
    const slam::LoopDetectionConfig config;
    out.push_back(MeasureBandwidth("simulated two-robot mission (default SimulatorConfig)",
                                   mission.robots, mission.T_world_sensor_truth, config));
    const auto read = slam::ReadScLioSamFolder(kaist_folder);
    if (!read.ok()) throw std::runtime_error(read.error);
    std::vector<std::vector<slam::Keyframe>> robots(2);
    std::vector<std::vector<Eigen::Isometry3d>> truth(2);
    for (size_t k = 0; k < read.keyframes.size(); ++k) {  // even -> robot 0, odd -> robot 1
        slam::Keyframe kf = read.keyframes[k];
        kf.robot = static_cast<int>(k % 2);
        kf.index = static_cast<int>(robots[kf.robot].size());
        truth[kf.robot].push_back(kf.T_odom_sensor);  // SC-A-LOAM's optimised poses
        robots[kf.robot].push_back(std::move(kf));
    }
    out.push_back(
        MeasureBandwidth("KAIST03 split even/odd into two robots", robots, truth, config));
    return out;
}

}  // namespace certislam::bin
