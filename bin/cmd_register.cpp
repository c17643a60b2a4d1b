// `certislam register SOURCE TARGET [--json]`: Scan Context distance and yaw of the pair, then
// GICP seeded by that yaw; prints T_target_source, fitness, sc_distance, yaw_deg, converged.
#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <numbers>
#include <string>

#include "bin/command.h"
#include "slam/frontend/registration.h"
#include "slam/frontend/scan_context.h"
#include "slam/io/cloud_io.h"

namespace certislam::bin {
namespace {

const char* StatusName(slam::RegistrationResult::Status status) {
    using S = slam::RegistrationResult::Status;
    switch (status) {
        case S::kAccepted:
            return "accepted";
        case S::kTooFewPoints:
            return "too_few_points";
        case S::kNotConverged:
            return "not_converged";
        case S::kLowFitness:
            return "low_fitness";
        case S::kDegenerate:
            return "degenerate";
    }
    return "unknown";
}

struct Outcome {
    slam::RegistrationResult registration;
    slam::ScanContextMatch sc;
    double seconds = 0.0;
};

void PrintText(const Outcome& o) {
    const auto& r = o.registration;
    std::printf("T_target_source\n");
    for (int i = 0; i < 4; ++i) {
        const auto& m = r.T_target_source.matrix();
        std::printf("  %12.8f %12.8f %12.8f %12.8f\n", m(i, 0), m(i, 1), m(i, 2), m(i, 3));
    }
    std::printf("status %s\nconverged %s\nfitness %.6f\ninlier_rmse_m %.6f\n", StatusName(r.status),
                r.converged ? "true" : "false", r.fitness, r.inlier_rmse_m);
    std::printf("sc_distance %.6f\nyaw_deg %.3f\ntranslation_eigen_ratio %.6f\nseconds %.3f\n",
                o.sc.distance, o.sc.yaw_rad * 180.0 / std::numbers::pi, r.translation_eigen_ratio,
                o.seconds);
}

nlohmann::json ToJson(const Outcome& o) {
    const auto& r = o.registration;
    nlohmann::json T = nlohmann::json::array();
    for (int i = 0; i < 4; ++i) {
        for (int c = 0; c < 4; ++c) T.push_back(r.T_target_source.matrix()(i, c));
    }
    nlohmann::json info = nlohmann::json::array();
    for (int i = 0; i < 6; ++i) {
        for (int c = 0; c < 6; ++c) info.push_back(r.information(i, c));
    }
    return {{"T_target_source", T},
            {"fitness", r.fitness},
            {"inlier_rmse_m", r.inlier_rmse_m},
            {"sc_distance", o.sc.distance},
            {"yaw_deg", o.sc.yaw_rad * 180.0 / std::numbers::pi},
            {"converged", r.converged},
            {"status", StatusName(r.status)},
            {"accepted", r.accepted()},
            {"translation_eigen_ratio", r.translation_eigen_ratio},
            {"information", info},
            {"num_source_points", r.num_source_points},
            {"num_target_points", r.num_target_points},
            {"seconds", o.seconds}};
}

int RunRegister(int argc, char** argv) {
    CLI::App app{"Register SOURCE onto TARGET (PCD, PLY or KITTI .bin), seeded by Scan Context"};
    std::string source_path, target_path;
    bool json = false, no_seed = false;
    slam::RegistrationConfig config;
    app.add_option("SOURCE", source_path, "cloud to move (PCD, PLY, KITTI .bin)")->required();
    app.add_option("TARGET", target_path, "reference cloud")->required();
    app.add_flag("--json", json, "print one JSON object");
    app.add_option("--voxel", config.voxel_m, "fine-stage voxel size (m)");
    app.add_flag("--no-sc-seed", no_seed, "start from identity instead of the Scan Context yaw");
    CLI11_PARSE(app, argc, argv);
    try {
        config.Validate();
    } catch (const std::invalid_argument& e) {
        std::fprintf(stderr, "certislam register: %s\n", e.what());
        return 2;
    }
    const slam::CloudReadResult source = slam::ReadCloud(source_path);
    const slam::CloudReadResult target = slam::ReadCloud(target_path);
    for (const auto* read : {&source, &target}) {
        if (!read->ok()) {
            std::fprintf(stderr, "certislam register: %s\n", read->error.c_str());
            return 1;
        }
    }
    const auto start = std::chrono::steady_clock::now();
    Outcome o;
    const slam::ScanContextConfig sc;
    o.sc = slam::ScanContextDistance(slam::MakeScanContext(source.cloud, sc),
                                     slam::MakeScanContext(target.cloud, sc));
    o.registration = slam::RegisterScans(source.cloud, target.cloud,
                                         slam::YawGuess(no_seed ? 0.0 : o.sc.yaw_rad), config);
    o.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (json) {
        std::printf("%s\n", ToJson(o).dump(2).c_str());
    } else {
        PrintText(o);
    }
    return 0;
}

const Registrar kRegister{"register",
                          "register two point clouds (Scan Context yaw seed + GICP): "
                          "T_target_source, fitness, sc_distance, yaw_deg, converged",
                          RunRegister};

}  // namespace
}  // namespace certislam::bin
