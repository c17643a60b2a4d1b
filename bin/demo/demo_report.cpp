// The demo's report: local-search runs in words and the whole report as JSON.
#include "bin/demo/demo_report.h"

#include <nlohmann/json.hpp>

#include "bin/command.h"

namespace certislam::bin {
namespace {

nlohmann::json LocalSearchJson(const DemoLocalSearch& ls) {
    return {{"start", ls.start},
            {"lm_status", ls.status},
            {"iterations", ls.iterations},
            {"initial_cost", ls.initial_cost},
            {"cost", ls.cost},
            {"cost_minus_certified", ls.gap},
            {"certified", ls.certified},
            {"verdict", ls.verdict},
            {"lambda_min", ls.lambda_min},
            {"rmse", ls.rmse}};
}

}  // namespace

DemoLocalSearch LocalSearchReport(const std::string& start, const certify::LocalSearchRun& run,
                                  double certified_cost, const std::vector<double>& rmse) {
    DemoLocalSearch out;
    out.start = start;
    out.status = run.status == slam::LmResult::Status::kConverged       ? "converged"
                 : run.status == slam::LmResult::Status::kNoConvergence ? "no convergence"
                                                                        : "failed";
    out.iterations = run.iterations;
    out.initial_cost = run.initial_cost;
    out.cost = run.cost;
    out.gap = run.cost - certified_cost;
    out.certified = run.certificate.status == certify::CertificateResult::Status::kCertified;
    out.verdict = certify::VerdictName(run.certificate.status);
    out.lambda_min = run.certificate.lambda_min;
    out.rmse = rmse;
    return out;
}

nlohmann::json DemoReportJson(const DemoReport& report) {
    nlohmann::json j;
    j["schema_version"] = kSchemaVersion;
    j["robots"] = nlohmann::json::array();
    for (const auto& r : report.robots) {
        j["robots"].push_back({{"id", r.id},
                               {"keyframes", r.keyframes},
                               {"rmse",
                                {{"odometry", r.odometry},
                                 {"one_time_alignment", r.one_time_alignment},
                                 {"local_search", r.local_search},
                                 {"local_search_from_alignment", r.local_search_aligned},
                                 {"certified", r.certified}}},
                               {"improvement_pct",
                                {{"over_one_time_alignment", r.improvement_over_alignment_pct},
                                 {"over_odometry", r.improvement_over_odometry_pct}}}});
    }
    j["certified"] = report.certified;
    j["lambda_min"] = report.lambda_min;
    if (report.certified_source == "pipeline") {
        j["lambda_min_relative"] = report.lambda_min_relative;
    }
    j["certified_source"] = report.certified_source;
    j["verdict"] = report.verdict;
    j["objective"] = report.cost;
    if (report.has_bound) {  // only a proven bound
        j["lower_bound"] = report.lower_bound;
        j["suboptimality_bound"] = report.suboptimality_bound;
        j["relative_suboptimality_bound"] = report.relative_suboptimality_bound;
    }
    j["cost"] = report.cost;
    j["local_search"] = LocalSearchJson(report.local_search);
    j["local_search_from_alignment"] = LocalSearchJson(report.local_search_aligned);
    j["rank"] = report.rank;
    j["rbcd_iterations"] = report.rbcd_iterations;
    j["inter_robot_loops"] = report.inter_robot_loops;
    j["intra_robot_loops"] = report.intra_robot_loops;
    j["candidates"] = report.candidates;
    j["bytes_sent"] = report.bytes_sent;
    j["bytes_note"] = report.bytes_note;
    j["seconds"] = report.seconds;
    j["keyframes_per_second"] = report.keyframes_per_second;
    j["timings"] = report.timings;
    j["pipeline"] = report.pipeline;
    j["mission"] = report.mission;
    j["actor_graph"] = report.actor_graph;
    j["scenario"] = report.scenario;
    j["loop_source"] = report.loop_source;
    j["warnings"] = report.warnings;
    j["rmse_alignment"] = "one SE(3) Umeyama alignment of the whole team (evo's ATE, translation)";
    return j;
}

}  // namespace certislam::bin
