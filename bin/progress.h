// What `run` and `robot` say while they work: a progress line on stderr (a bar on a terminal,
// plain lines otherwise) and snapshots of the outputs, so a long or stuck run can be read early.
#pragma once

#include <chrono>
#include <functional>
#include <string>
#include <vector>

#include "actors/solver_actor.h"

namespace CLI {
class App;
}

namespace certislam::bin {

/// How often to report and snapshot; zero turns each off.
struct ProgressConfig {
    std::chrono::milliseconds line_period{2000};      ///< a progress line (0: none)
    std::chrono::milliseconds snapshot_period{5000};  ///< outputs rewritten (0: none)
    bool terminal = false;  ///< stderr is a terminal: one line redrawn, with a bar
};

/// The team's state in one line: robots final and certified, keyframes, inter-robot loops,
/// block updates, the last verdict heard, seconds. With `bar_width` > 0 a bar of the robots done.
std::string ProgressLine(const std::vector<actors::SolverSnapshot>& snapshots, double seconds,
                         int bar_width);

/// Calls Tick() from the command's polling loop; prints and snapshots at their periods.
class Progress {
  public:
    /// `command` prefixes plain lines; `snapshot` writes the outputs (called at its period).
    Progress(std::string command, ProgressConfig config, std::function<void()> snapshot);
    /// Reports when a period has passed; `snapshots` gives the robots' solver states now (called
    /// only then: a snapshot copies trajectories).
    void Tick(const std::function<std::vector<actors::SolverSnapshot>()>& snapshots,
              double seconds);
    /// Ends a redrawn line (before the report is printed).
    void Finish();
    /// Snapshots written so far.
    int snapshots_written() const { return snapshots_written_; }

  private:
    std::string command_;
    ProgressConfig config_;
    std::function<void()> snapshot_;
    std::chrono::steady_clock::time_point last_line_;
    std::chrono::steady_clock::time_point last_snapshot_;
    bool drawn_ = false;
    int snapshots_written_ = 0;
};

/// Polls `done` every 50 ms until it holds or `timeout_s` seconds after `start`, ticking
/// `progress` with `states` and the seconds since `start`; true when done.
bool WaitWithProgress(const std::function<bool()>& done,
                      std::chrono::steady_clock::time_point start, double timeout_s,
                      Progress* progress,
                      const std::function<std::vector<actors::SolverSnapshot>()>& states);

/// Adds `--progress S` and `--snapshot S` to a command; `what` names the files a snapshot
/// rewrites.
void AddProgressOptions(CLI::App& app, const std::string& what, double* progress_s,
                        double* snapshot_s);

/// ProgressConfig from the commands' `--progress S` and `--snapshot S` (seconds, 0: off);
/// `terminal` from whether stderr is a terminal.
ProgressConfig MakeProgressConfig(double line_s, double snapshot_s);

}  // namespace certislam::bin
