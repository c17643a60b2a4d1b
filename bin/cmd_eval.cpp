// `certislam eval`: ATE RMSE (Umeyama SE(3) alignment) and RPE of estimated trajectories, evo's
// conventions, jointly across robots and per robot.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "bin/command.h"
#include "slam/eval/trajectory_metrics.h"
#include "slam/io/trajectory_io.h"

namespace certislam::bin {
namespace {

struct EvalOptions {
    std::vector<std::string> gt, est;
    std::string format = "tum";
    std::string align = "se3";
    double max_diff_s = 0.01;
    bool json = false;
};

void PrintText(const EvalOptions& options, const slam::TeamErrors& team) {
    std::printf("alignment: %s (joint across %zu trajectories), %d pose pairs\n",
                options.align.c_str(), team.robots.size(), team.pairs);
    std::printf("%-4s %-30s %8s %12s %16s %12s\n", "#", "estimate", "pairs", "ate_rmse_m",
                "ate_own_align_m", "rpe_rmse_m");
    for (size_t k = 0; k < team.robots.size(); ++k) {
        const auto& r = team.robots[k];
        std::printf("%-4zu %-30s %8d %12.6f %16.6f %12.6f\n", k, options.est[k].c_str(), r.pairs,
                    r.ate_rmse, r.ate_rmse_own, r.rpe_rmse);
    }
    std::printf("ate_rmse %.6f m   rpe_rmse %.6f m\n", team.ate_rmse, team.rpe_rmse);
}

nlohmann::json ToJson(const EvalOptions& options, const slam::TeamErrors& team) {
    nlohmann::json j;
    j["alignment"] = options.align;
    j["format"] = options.format;
    j["pairs"] = team.pairs;
    j["ate_rmse"] = team.ate_rmse;
    j["rpe_rmse"] = team.rpe_rmse;
    nlohmann::json T = nlohmann::json::array();
    for (int r = 0; r < 4; ++r) {
        for (int c = 0; c < 4; ++c) T.push_back(team.T_gt_est.matrix()(r, c));
    }
    j["T_gt_est"] = T;
    j["robots"] = nlohmann::json::array();
    for (size_t k = 0; k < team.robots.size(); ++k) {
        const auto& r = team.robots[k];
        j["robots"].push_back({{"gt", options.gt[k]},
                               {"est", options.est[k]},
                               {"pairs", r.pairs},
                               {"ate_rmse", r.ate_rmse},
                               {"ate_rmse_own_alignment", r.ate_rmse_own},
                               {"rpe_rmse", r.rpe_rmse}});
    }
    return j;
}

int RunEval(int argc, char** argv) {
    EvalOptions options;
    CLI::App app{
        "Trajectory errors: ATE RMSE after Umeyama SE(3) alignment and RPE (evo's "
        "conventions). Several --gt/--est pairs (one per robot) are aligned jointly."};
    app.add_option("--gt", options.gt, "ground-truth trajectory (repeat: one per robot)")
        ->required();
    app.add_option("--est", options.est, "estimated trajectory (repeat, same order as --gt)")
        ->required();
    app.add_option("--format", options.format, "file format")
        ->check(CLI::IsMember({"tum", "kitti"}));
    app.add_option("--align", options.align, "alignment")->check(CLI::IsMember({"se3", "none"}));
    app.add_option("--max-diff", options.max_diff_s, "TUM association: max stamp difference, s");
    app.add_flag("--json", options.json, "print JSON");
    CLI11_PARSE(app, argc, argv);
    if (options.gt.size() != options.est.size()) {
        std::fprintf(stderr, "certislam eval: %zu --gt but %zu --est files: give them in pairs\n",
                     options.gt.size(), options.est.size());
        return 2;
    }
    slam::TrajectoryFormat format{};
    slam::ParseTrajectoryFormat(options.format, &format);
    slam::AssociationConfig association;
    association.by_index = format == slam::TrajectoryFormat::kKitti;
    association.max_diff_s = options.max_diff_s;
    association.Validate();
    std::vector<slam::AssociatedPoses> robots;
    for (size_t k = 0; k < options.gt.size(); ++k) {
        const auto gt = slam::ReadTrajectory(options.gt[k], format);
        const auto est = slam::ReadTrajectory(options.est[k], format);
        for (const auto* read : {&gt, &est}) {
            if (read->status != slam::TrajectoryReadResult::Status::kOk) {
                std::fprintf(stderr, "certislam eval: %s\n", read->error.c_str());
                return 1;
            }
        }
        robots.push_back(slam::Associate(gt.trajectory, est.trajectory, association));
    }
    const auto team = slam::EvaluateTeam(robots, options.align == "se3");
    if (team.status != slam::TeamErrors::Status::kOk) {
        std::fprintf(stderr, "certislam eval: no pose pairs associated (max diff %g s)\n",
                     options.max_diff_s);
        return 1;
    }
    if (options.json) {
        std::printf("%s\n", ToJson(options, team).dump(2).c_str());
    } else {
        PrintText(options, team);
    }
    return 0;
}

const Registrar kRegistrar{"eval", "trajectory errors: ATE RMSE (Umeyama SE(3)) and RPE", RunEval};

}  // namespace
}  // namespace certislam::bin
