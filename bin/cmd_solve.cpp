// `certislam solve FILE`: certifiably optimal pose-graph optimisation of a g2o file (or of a
// multi-robot CSV directory) with RBCD on the rank-r relaxation, or the LM baseline.
#include <sys/resource.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "bin/command.h"
#include "bin/solve_distributed.h"
#include "bin/solve_output.h"
#include "bin/verdict.h"
#include "certify/pose_graph_solver.h"
#include "slam/io/g2o_io.h"
#include "slam/io/multirobot_io.h"

namespace certislam::bin {
namespace {

constexpr double kProgressPeriodSeconds = 1.0;  ///< at most one progress line per second

struct SolveOptions {
    std::string file;
    int robots = -1;  // -1: 1 for a g2o file, the file's own robots for a CSV directory
    std::string method = "rbcd";
    int rank = 0;
    bool robust = false;
    std::string out;
    bool json = false;
    bool quiet = false;
    bool distributed = false;
    std::string transport = "inproc";
    std::string eigensolver;  ///< empty: the certifier's default (lobpcg)
    int overlap = -1;         ///< --distributed: solver.rounds_overlap; -1: its default
    int finish_after = -1;    ///< --distributed: solver.finish_after_rounds; -1: its default
    int max_rounds = -1;      ///< --distributed: solver.rounds_max; -1: its default
    double timeout_s = 600.0;
    double max_relative_bound = certify::CertificateConfig{}.max_relative_bound;
};

double PeakRssMb() {
    rusage usage{};
    getrusage(RUSAGE_SELF, &usage);
    return static_cast<double>(usage.ru_maxrss) / 1024.0;  // ru_maxrss is in KiB on Linux
}

double CpuSeconds() {
    rusage usage{};
    getrusage(RUSAGE_SELF, &usage);
    const auto seconds = [](const timeval& t) { return t.tv_sec + 1e-6 * t.tv_usec; };
    return seconds(usage.ru_utime) + seconds(usage.ru_stime);
}

nlohmann::json ToJson(const SolveOptions& o, const slam::PoseGraph& graph, int robots,
                      const certify::PoseGraphSolverResult& r) {
    const auto& c = r.certificate;
    nlohmann::json j = {
        {"schema_version", kSchemaVersion},
        {"file", o.file},
        {"method", o.method},
        {"path", "in_process"},
        {"objective", r.cost},
        {"cost", r.cost},
        {"certified", r.status == certify::PoseGraphSolverResult::Status::kCertified},
        {"verdict", certify::VerdictName(r.status)},
        {"gradient_norm", c.gradient_norm},
        {"gradient_tolerance", c.gradient_tolerance},
        {"rank", r.rank},
        {"iterations", r.iterations},
        {"escapes", r.escapes},
        {"seconds", r.seconds},
        {"certify_seconds", c.seconds},
        {"peak_rss_mb", PeakRssMb()},
        {"poses", graph.n},
        {"edges", static_cast<int>(graph.edges.size())},
        {"edges_used", r.edges_used},
        {"robots", robots},
        {"robust", o.robust}};
    if (!r.reason.empty()) j["reason"] = r.reason;
    if (o.robust) {
        j["rejected_edges"] = r.rejected_edges;
        j["gnc_iterations"] = r.gnc_iterations;
        j["gnc_reinstated"] = r.gnc_reinstated;
    }
    if (o.method == "lm") {
        j["local_search_cost"] = r.local_search_cost;
        j["polish_iterations"] = r.polish_iterations;
    }
    // Only what was computed and proven: no eigenvalue at a non-critical point, no bound
    // unless S + eta D was shown PSD.
    if (r.status != certify::PoseGraphSolverResult::Status::kNotCritical) {
        j["lambda_min"] = c.lambda_min;
        j["lambda_min_relative"] = c.lambda_min_relative;
    }
    if (r.status == certify::PoseGraphSolverResult::Status::kNotOptimal) {
        j["escape_descent"] = c.escape_descent;
    }
    if (r.has_bound) {
        j["lower_bound"] = r.lower_bound;
        j["suboptimality_bound"] = r.suboptimality_bound;
        j["relative_suboptimality_bound"] = r.relative_suboptimality_bound;
    }
    return j;
}

void PrintText(const slam::PoseGraph& graph, int robots, const certify::PoseGraphSolverResult& r) {
    const auto& c = r.certificate;
    std::printf("poses %d   edges %zu (used %d)   robots %d   rank %d\n", graph.n,
                graph.edges.size(), r.edges_used, robots, r.rank);
    std::printf("objective %.10g   verdict: %s%s%s\n", r.cost, certify::VerdictName(r.status),
                r.reason.empty() ? "" : " (", r.reason.empty() ? "" : (r.reason + ")").c_str());
    if (r.status == certify::PoseGraphSolverResult::Status::kNotCritical) {
        std::printf("gradient norm %.3e > tolerance %.3e: no bound\n", c.gradient_norm,
                    c.gradient_tolerance);
    } else {
        std::printf("lambda_min %.3e (relative %.3e)", c.lambda_min, c.lambda_min_relative);
        if (r.status == certify::PoseGraphSolverResult::Status::kNotOptimal) {
            std::printf("   escape descent %.3e", c.escape_descent);
        }
        std::printf("\n");
    }
    if (r.has_bound) {
        std::printf("suboptimality bound %.3e (relative %.3e)   lower bound %.10g\n",
                    r.suboptimality_bound, r.relative_suboptimality_bound, r.lower_bound);
    } else {
        std::printf("suboptimality bound: none proven\n");
    }
    std::printf("iterations %d   escapes %d   %.3f s (certificate %.3f s)   peak RSS %.1f MB\n",
                r.iterations, r.escapes, r.seconds, c.seconds, PeakRssMb());
}

slam::PoseGraphReadResult Read(const std::string& path) {
    if (std::filesystem::is_directory(path)) return slam::ReadMultiRobotCsv(path);
    return slam::ReadG2o(path);
}

/// The options of `solve` into `o`.
void AddOptions(CLI::App& app, SolveOptions& o) {
    app.option_defaults()->always_capture_default();
    app.add_option("file", o.file, "g2o file, or a multi-robot CSV directory")->required();
    app.add_option("--robots", o.robots,
                   "contiguous robot blocks (default 1; a CSV directory: its own robots)")
        ->check(CLI::PositiveNumber);
    app.add_option("--method", o.method, "rbcd (certified) or lm (baseline)")
        ->check(CLI::IsMember({"rbcd", "lm"}));
    app.add_option("--rank", o.rank, "starting relaxation rank r (default d)")
        ->check(CLI::PositiveNumber);
    app.add_flag("--robust", o.robust, "GNC-TLS against outlier loop closures, then certify");
    app.add_option("--out", o.out,
                   "write the solution (.g2o, .tum or .kitti; pose 0 where the input has it)");
    app.add_flag("--json", o.json, "print one JSON object on stdout");
    app.add_flag("--quiet", o.quiet, "no progress lines on stderr");
    app.add_option("--max-relative-bound", o.max_relative_bound,
                   "certified needs a relative suboptimality bound at most this, in (0, 1)");
    app.add_flag("--distributed", o.distributed,
                 "each robot its own solver and certifier actors over sockets (3D graphs)");
    app.add_option("--transport", o.transport,
                   "--distributed: inproc (one process), or ipc / tcp (a `certislam robot` "
                   "process per robot on this host)")
        ->check(CLI::IsMember({"inproc", "ipc", "tcp"}));
    app.add_option("--eigensolver", o.eigensolver,
                   "--distributed: the certificate's eigen-solver, lobpcg (block-Jacobi "
                   "preconditioned; default) or lanczos (certifier.eigensolver)")
        ->check(CLI::IsMember({"lanczos", "lobpcg"}));
    app.add_option("--overlap", o.overlap,
                   "--distributed: each robot's sweep also moves its later-sweeping neighbours' "
                   "poses within this many edges (solver.rounds_overlap; 0: own poses only)")
        ->check(CLI::Range(0, 16));
    app.add_option("--finish-after-rounds", o.finish_after,
                   "--distributed: from this round on, rounds too slow to converge in "
                   "--max-rounds hand the team to its second-order finish "
                   "(solver.finish_after_rounds, default 50; 0: none)")
        ->check(CLI::Range(0, 1000000));
    app.add_option("--max-rounds", o.max_rounds,
                   "--distributed: rounds at most, then the finish (solver.rounds_max, default "
                   "1000)")
        ->check(CLI::Range(1, 1000000));
    app.add_option("--timeout", o.timeout_s, "--distributed: give up after this many seconds")
        ->check(CLI::PositiveNumber);
}

/// Options that do not go together: prints why and returns kExitUsage (else kExitDone).
int CheckOptionCombinations(const SolveOptions& o) {
    if (!(o.max_relative_bound > 0.0 && o.max_relative_bound < 1.0)) {
        std::fprintf(stderr, "certislam solve: error: --max-relative-bound: %g is not in (0, 1)\n",
                     o.max_relative_bound);
        return kExitUsage;
    }
    if (o.distributed && (o.method != "rbcd" || o.robust || o.rank > 0 || !o.out.empty())) {
        std::fprintf(stderr,
                     "certislam solve: error: --distributed: no --method lm, --robust, "
                     "--rank or --out\n");
        return kExitUsage;
    }
    if (!o.distributed && (o.overlap >= 0 || o.finish_after >= 0 || o.max_rounds > 0)) {
        std::fprintf(stderr,
                     "certislam solve: error: --overlap, --finish-after-rounds and --max-rounds "
                     "need --distributed\n");
        return kExitUsage;
    }
    if (!o.distributed && !o.eigensolver.empty()) {
        std::fprintf(stderr, "certislam solve: error: --eigensolver needs --distributed\n");
        return kExitUsage;
    }
    if (!o.distributed && o.transport != "inproc") {
        std::fprintf(stderr, "certislam solve: error: --transport %s needs --distributed\n",
                     o.transport.c_str());
        return kExitUsage;
    }
    return kExitDone;
}

int RunSolve(int argc, char** argv) {
    SolveOptions o;
    CLI::App app{"Certifiably optimal pose-graph optimisation (RBCD + dual certificate)"};
    AddOptions(app, o);
    CLI11_PARSE(app, argc, argv);
    if (const int code = CheckOptionCombinations(o); code != kExitDone) return code;
    if (!o.out.empty() && !SolutionFormatError(o.out).empty()) {
        std::fprintf(stderr, "certislam solve: error: %s\n", SolutionFormatError(o.out).c_str());
        return 1;
    }
    const slam::PoseGraphReadResult read = Read(o.file);
    if (!read.ok()) {
        std::fprintf(stderr, "certislam solve: error: %s\n", read.error.c_str());
        return 1;
    }
    const slam::PoseGraph& graph = read.graph;
    if (o.distributed) {
        DistributedSolveOptions d;
        d.file = o.file;
        d.robots = o.robots;
        d.timeout_s = o.timeout_s;
        d.json = o.json;
        d.max_relative_bound = o.max_relative_bound;
        d.transport = o.transport;
        if (!o.eigensolver.empty()) d.eigensolver = o.eigensolver;
        d.overlap = o.overlap;
        d.finish_after = o.finish_after;
        d.max_rounds = o.max_rounds;
        return RunDistributedSolve(graph, d);
    }
    certify::PoseGraphSolverConfig config;
    config.method = o.method == "lm" ? certify::PoseGraphSolverConfig::Method::kLm
                                     : certify::PoseGraphSolverConfig::Method::kRbcd;
    config.robots = o.robots > 0 ? o.robots : (std::filesystem::is_directory(o.file) ? 0 : 1);
    config.rank = o.rank;
    config.robust = o.robust;
    config.staircase.certificate.max_relative_bound = o.max_relative_bound;
    auto last = std::chrono::steady_clock::now() - std::chrono::hours(1);
    const auto progress = [&](const std::string& stage, int rank, double cost, double grad,
                              double seconds) {
        const auto now = std::chrono::steady_clock::now();
        if (o.quiet || (stage == "rbcd" &&
                        now - last < std::chrono::duration<double>(kProgressPeriodSeconds))) {
            return;
        }
        last = now;
        std::fprintf(stderr, "[solve %7.2f s] %-8s rank %d  cost %.10g  grad %.3e\n", seconds,
                     stage.c_str(), rank, cost, grad);
    };
    const double cpu_start = CpuSeconds();
    const certify::PoseGraphSolverResult result = certify::SolvePoseGraph(graph, config, progress);
    const double cpu_seconds = CpuSeconds() - cpu_start;
    const int robots = config.robots > 0   ? config.robots
                       : graph.ids.empty() ? 1
                                           : graph.ids.back().robot + 1;
    if (!o.out.empty()) {
        std::string error;
        if (!WriteSolution(o.out, graph, result.solved_graph, result.poses, &error)) {
            std::fprintf(stderr, "certislam solve: error: %s\n", error.c_str());
            return 1;
        }
    }
    if (o.json) {
        nlohmann::json j = ToJson(o, graph, robots, result);
        j["cpu_seconds"] = cpu_seconds;  // all threads; wall `seconds` inflates on a loaded host
        std::printf("%s\n", j.dump(2).c_str());
    } else {
        PrintText(graph, robots, result);
    }
    return result.status == certify::PoseGraphSolverResult::Status::kCertified ? kExitDone
                                                                               : kExitNotCertified;
}

const Registrar kRegistrar{
    "solve", "certifiably optimal pose-graph optimisation of a g2o file (RBCD)", RunSolve};

}  // namespace
}  // namespace certislam::bin
