// Progress lines and periodic snapshots of `run` and `robot`.
#include "bin/progress.h"

#include <unistd.h>

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstdio>
#include <sstream>
#include <thread>
#include <utility>

#include "bin/verdict.h"

namespace certislam::bin {

std::string ProgressLine(const std::vector<actors::SolverSnapshot>& snapshots, double seconds,
                         int bar_width) {
    int done = 0, keyframes = 0, loops = 0;
    std::uint64_t steps = 0;
    std::string verdict = "none";
    // The solvers' phase: the graph still growing, synchronous rounds once it is final, converged.
    bool all_final = !snapshots.empty(), all_converged = !snapshots.empty();
    std::uint64_t rounds = 0;
    for (const auto& s : snapshots) {
        all_final = all_final && s.final;
        all_converged = all_converged && s.rounds_converged;
        rounds = std::max(rounds, s.team_rounds);
        const bool certified = s.report && s.report->verdict() == v1::CERTIFICATE_VERDICT_CERTIFIED;
        done += s.final && certified ? 1 : 0;
        keyframes += s.num_poses;
        loops += s.inter_robot_loops;
        steps += s.steps;
        if (s.report) verdict = VerdictName(s.report->verdict());
    }
    const int robots = static_cast<int>(snapshots.size());
    std::ostringstream out;
    if (bar_width > 0 && robots > 0) {
        const int filled = bar_width * done / robots;
        out << "[" << std::string(filled, '#') << std::string(bar_width - filled, '.') << "] ";
    }
    // Each robot counts an inter-robot loop it holds an end of: a loop between two is counted
    // twice in one process, once by a robot alone.
    out << done << "/" << robots << " robots certified, " << keyframes << " keyframes, " << loops
        << " inter-robot loop ends, " << steps << " block updates, ";
    if (!all_final) {
        out << "graph growing";
    } else {
        out << rounds << " team rounds" << (all_converged ? " (converged)" : "");
    }
    out << ", last verdict: " << verdict << ", " << static_cast<int>(seconds) << " s";
    return out.str();
}

Progress::Progress(std::string command, ProgressConfig config, std::function<void()> snapshot)
    : command_(std::move(command)),
      config_(config),
      snapshot_(std::move(snapshot)),
      last_line_(std::chrono::steady_clock::now()),
      last_snapshot_(last_line_) {}

void Progress::Tick(const std::function<std::vector<actors::SolverSnapshot>()>& snapshots,
                    double seconds) {
    const auto now = std::chrono::steady_clock::now();
    if (config_.line_period.count() > 0 && now - last_line_ >= config_.line_period) {
        last_line_ = now;
        const auto states = snapshots();
        if (config_.terminal) {
            std::fprintf(stderr, "\r\033[K%s", ProgressLine(states, seconds, 20).c_str());
            drawn_ = true;
        } else {
            std::fprintf(stderr, "%s: %s\n", command_.c_str(),
                         ProgressLine(states, seconds, 0).c_str());
        }
        std::fflush(stderr);
    }
    if (snapshot_ && config_.snapshot_period.count() > 0 &&
        now - last_snapshot_ >= config_.snapshot_period) {
        last_snapshot_ = now;
        snapshot_();
        ++snapshots_written_;
    }
}

void Progress::Finish() {
    if (drawn_) std::fprintf(stderr, "\n");
    drawn_ = false;
}

bool WaitWithProgress(const std::function<bool()>& done,
                      std::chrono::steady_clock::time_point start, double timeout_s,
                      Progress* progress,
                      const std::function<std::vector<actors::SolverSnapshot>()>& states) {
    const auto deadline = start + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                      std::chrono::duration<double>(timeout_s));
    bool finished = false;
    while (!finished && std::chrono::steady_clock::now() < deadline) {
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
        finished = done();
        const double seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        progress->Tick(states, seconds);
    }
    progress->Finish();
    return finished;
}

void AddProgressOptions(CLI::App& app, const std::string& what, double* progress_s,
                        double* snapshot_s) {
    app.add_option("--progress", *progress_s, "a progress line on stderr every S seconds (0: none)")
        ->check(CLI::NonNegativeNumber);
    app.add_option("--snapshot", *snapshot_s,
                   "rewrite --out's " + what + " every S seconds (0: only at the end)")
        ->check(CLI::NonNegativeNumber);
}

ProgressConfig MakeProgressConfig(double line_s, double snapshot_s) {
    ProgressConfig config;
    config.line_period = std::chrono::milliseconds(static_cast<long long>(line_s * 1000.0));
    config.snapshot_period = std::chrono::milliseconds(static_cast<long long>(snapshot_s * 1000.0));
    config.terminal = ::isatty(STDERR_FILENO) != 0;
    return config;
}

}  // namespace certislam::bin
