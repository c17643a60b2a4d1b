// The report of a pose-graph team run: shared by `solve --distributed` and each robot process.
#include "bin/team_result.h"

#include <sys/resource.h>

#include "bin/command.h"
#include "bin/verdict.h"

namespace certislam::bin {
namespace {

double PeakRssMb() {
    rusage usage{};
    getrusage(RUSAGE_SELF, &usage);
    return static_cast<double>(usage.ru_maxrss) / 1024.0;  // KiB on Linux
}

}  // namespace

nlohmann::json TeamResultJson(const actors::PoseGraphTeamResult& r, int robots,
                              const std::string& transport) {
    const v1::CertificateReport report = r.report.value_or(v1::CertificateReport{});
    const bool certified = r.done && report.verdict() == v1::CERTIFICATE_VERDICT_CERTIFIED;
    // The file's cost: the team's plus the constant of its merged parallel edges (none heard: 0).
    const double cost = r.report ? report.objective() + r.cost_offset : 0.0;
    nlohmann::json j = {{"schema_version", kSchemaVersion},
                        {"method", "rbcd"},
                        {"path", "distributed"},
                        {"transport", transport},
                        {"objective", cost},
                        {"cost", cost},
                        {"cost_offset", r.cost_offset},
                        {"certified", certified},
                        {"verdict", VerdictName(report.verdict())},
                        {"certificate_path", CertificatePathName(report.path())},
                        {"rank", r.rank},
                        {"iterations", r.iterations},
                        {"seconds", r.seconds},
                        {"seconds_to_converged", r.seconds_to_converged},
                        {"seconds_to_certified", r.seconds_to_certified},
                        {"certificate_rounds", r.certificate_rounds},
                        {"lanczos_steps", r.lanczos_steps},
                        {"certificate_seconds", r.certificate_seconds},
                        {"escapes", r.escapes},
                        {"solver_mode", r.solver_mode},
                        {"restarts", r.restarts},
                        {"rejected_proposals", r.rejected_proposals},
                        {"round_resends", r.round_resends},
                        {"overlap_ends", r.overlap_ends},
                        {"central_fallbacks", r.fallbacks},
                        {"finish",
                         {{"status", r.finish_status},
                          {"steps", r.finish_steps},
                          {"cg_iterations", r.finish_cg_iterations},
                          {"exchanges", r.finish_exchanges},
                          {"reductions", r.finish_reductions},
                          {"dropped", r.finish_dropped},
                          {"seconds", r.finish_seconds}}},
                        {"bytes_between_robots",
                         {{"total", r.bytes_between_robots}, {"by_actor", r.bytes_by_actor}}},
                        {"peak_rss_mb", PeakRssMb()},
                        {"robots", robots}};
    nlohmann::json by_robot = nlohmann::json::object(), steps = nlohmann::json::object();
    for (const auto& [robot, bytes] : r.bytes_by_robot) by_robot[std::to_string(robot)] = bytes;
    for (const auto& [robot, n] : r.iterations_by_robot) steps[std::to_string(robot)] = n;
    j["bytes_between_robots"]["by_robot"] = by_robot;
    j["iterations_by_robot"] = steps;
    if (r.report) {
        j["lambda_min"] = report.lambda_min();
        // Only a proven bound (S + eta D shown PSD), as `solve` and `run` print it; the file's
        // lower bound adds the merged parallel edges' constant, as its cost does.
        if (r.done && report.has_bound()) {
            j["lower_bound"] = report.lower_bound() + r.cost_offset;
            j["suboptimality_bound"] = report.suboptimality_bound();
            // The certifier's own (its noise floor for an optimum of 0) unless edges were merged.
            j["relative_suboptimality_bound"] = r.cost_offset == 0.0
                                                    ? report.relative_suboptimality_bound()
                                                    : report.suboptimality_bound() / cost;
        }
    }
    if (!r.done) j["reason"] = "not certified before the timeout";
    return j;
}

}  // namespace certislam::bin
