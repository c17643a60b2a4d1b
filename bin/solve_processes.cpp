// The distributed solve as separate robot processes: a team configuration in a private folder,
// one `certislam-robot` (else `certislam robot`) per robot (killed with this process), their
// reports merged.
#include "bin/solve_processes.h"

#include <fcntl.h>
#include <google/protobuf/util/json_util.h>
#include <netinet/in.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>

#include "actors/solver_actor.h"
#include "bin/command.h"
#include "certify/pipeline/team_rounds.h"
#include "slam/core/graph_split.h"

namespace certislam::bin {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

constexpr double kGraceSeconds = 30.0;  ///< past --timeout before the robots are killed
constexpr int kEdgePorts = 7;           ///< tcp ports per robot: base_port + 1 .. + 7
constexpr int kFirstPort = 20000;       ///< robots' tcp ports from here up to the ephemeral range
constexpr int kDefaultEphemeralLow = 32768;  ///< Linux's defaults when /proc does not say
constexpr int kDefaultEphemeralHigh = 60999;
constexpr int kMinPorts = 1000;       ///< below the ephemeral range only when this many fit there
constexpr long long kPidSpread = 97;  ///< slots between the starts of consecutive pids
constexpr int kRetrySpread = 331;     ///< slots between the starts of a solve's attempts
/// Teams started at most, for tcp: another process may bind a checked port before a robot does.
constexpr int kPortAttempts = 3;
constexpr const char* kPortTaken = "Address already in use";  ///< ZeroMQ's EADDRINUSE message

/// One robot process.
struct Child {
    int robot = 0;
    pid_t pid = -1;
    std::string out, log;  ///< its stdout (the JSON report) and stderr
    int status = 0;        ///< wait status
    bool exited = false;
    double peak_rss_mb = 0.0;  ///< its ru_maxrss, from wait4
};

/// True when no process listens on 127.0.0.1:base+1 .. base+7 now.
bool PortsFree(int base) {
    for (int port = base + 1; port <= base + kEdgePorts; ++port) {
        const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
        if (fd < 0) return false;
        sockaddr_in addr{};
        addr.sin_family = AF_INET;
        addr.sin_port = htons(static_cast<std::uint16_t>(port));
        addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
        const bool ok = ::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) == 0;
        ::close(fd);
        if (!ok) return false;
    }
    return true;
}

/// The robots' ports, [first, end): from kFirstPort up to the kernel's ephemeral range, else
/// above it (outgoing connections take ports from that range, so a listener there can lose its
/// port between the check and the bind).
std::pair<int, int> PortRange() {
    std::ifstream in("/proc/sys/net/ipv4/ip_local_port_range");
    int low = kDefaultEphemeralLow, high = kDefaultEphemeralHigh;
    if (!(in >> low >> high)) {
        low = kDefaultEphemeralLow;
        high = kDefaultEphemeralHigh;
    }
    return low >= kFirstPort + kMinPorts ? std::pair{kFirstPort, low} : std::pair{high + 1, 65536};
}

/// Base ports for `robots` robots, each with 7 free ports, from a start spread by the pid and the
/// attempt (concurrent solves and retries start apart).
std::vector<int> FreeBasePorts(int robots, int attempt) {
    const int stride = kEdgePorts + 1;
    const auto [first_port, end_port] = PortRange();
    const int slots = std::max(0, (end_port - first_port) / stride);
    if (slots < robots) throw std::runtime_error("no free tcp ports on 127.0.0.1");
    std::vector<int> bases;
    const auto start = (static_cast<long long>(::getpid()) * kPidSpread + attempt * kRetrySpread);
    const int first = static_cast<int>(start % slots);
    for (int i = 0; i < slots && static_cast<int>(bases.size()) < robots; ++i) {
        const int base = first_port + ((first + i) % slots) * stride;
        if (PortsFree(base)) bases.push_back(base);
    }
    if (static_cast<int>(bases.size()) < robots) {
        throw std::runtime_error("no free tcp ports on 127.0.0.1");
    }
    return bases;
}

/// The team configuration (JSON, which YAML reads) of the split: a pose-graph source with the
/// partition's vertex ranges, this solve's threshold and quiet time.
nlohmann::json TeamConfigOf(const DistributedSolveOptions& o, const slam::Partition& partition,
                            const fs::path& dir, int attempt) {
    nlohmann::json config;
    const int robots = partition.num_robots();
    for (int k = 0; k < robots; ++k) config["robots"].push_back(k);
    config["quiet_s"] = o.quiet_s;
    config["certifier"]["max_relative_bound"] = o.max_relative_bound;
    config["certifier"]["eigensolver"] = o.eigensolver;
    if (o.overlap >= 0) config["solver"]["rounds_overlap"] = o.overlap;
    if (o.finish_after >= 0) config["solver"]["finish_after_rounds"] = o.finish_after;
    if (o.max_rounds > 0) config["solver"]["rounds_max"] = o.max_rounds;
    config["source"] = {{"kind", "pose_graph"}, {"graph", fs::absolute(o.file).string()}};
    for (int k = 0; k < robots; ++k) {
        config["source"]["ranges"][std::to_string(k)] = {{"begin", partition.begin[k]},
                                                         {"end", partition.begin[k + 1]}};
    }
    const std::vector<int> ports =
        o.transport == "tcp" ? FreeBasePorts(robots, attempt) : std::vector<int>{};
    for (int k = 0; k < robots; ++k) {
        config["network"][std::to_string(k)] =
            o.transport == "tcp" ? nlohmann::json{{"host", "127.0.0.1"}, {"base_port", ports[k]}}
                                 : nlohmann::json{{"ipc_dir", dir.string()}};
    }
    return config;
}

/// Starts `ROBOT-COMMAND CONFIG --id K --json --timeout T`, stdout and stderr to files; the child
/// dies with this process (PR_SET_PDEATHSIG).
pid_t Spawn(const std::vector<std::string>& args, const std::string& out, const std::string& log) {
    const int out_fd = ::open(out.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
    const int log_fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
    if (out_fd < 0 || log_fd < 0) {
        if (out_fd >= 0) ::close(out_fd);
        if (log_fd >= 0) ::close(log_fd);
        throw std::runtime_error((out_fd < 0 ? out : log) + ": cannot create");
    }
    std::vector<char*> argv;
    argv.reserve(args.size() + 1);
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    const pid_t parent = ::getpid();
    const pid_t pid = ::fork();
    if (pid == 0) {  // only async-signal-safe calls until exec
        ::prctl(PR_SET_PDEATHSIG, SIGKILL);
        if (::getppid() != parent) ::_exit(127);
        ::dup2(out_fd, STDOUT_FILENO);
        ::dup2(log_fd, STDERR_FILENO);
        ::execv(argv[0], argv.data());
        ::_exit(127);
    }
    ::close(out_fd);
    ::close(log_fd);
    if (pid < 0) throw std::runtime_error("fork failed for " + args[0]);
    return pid;
}

/// True when a robot's exit ends the team: anything but done or not certified (a bad input, a
/// port taken, a crash).
bool Failed(int status) {
    const int code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    return code != kExitDone && code != kExitNotCertified;
}

/// Waits for every child (peak RSS from wait4). The first child that fails stops the others (they
/// would wait for it until their timeout), and so does `deadline`. Returns the index of the first
/// that failed, or -1.
int WaitAll(std::vector<Child>* children, Clock::time_point deadline) {
    size_t running = children->size();
    bool killed = false;
    int failed = -1;
    const auto kill_running = [&] {
        for (const auto& c : *children) {
            if (!c.exited) ::kill(c.pid, SIGKILL);
        }
        killed = true;
    };
    while (running > 0) {
        int status = 0;
        rusage usage{};
        const pid_t pid = ::wait4(-1, &status, WNOHANG, &usage);
        if (pid > 0) {
            for (size_t k = 0; k < children->size(); ++k) {
                Child& c = (*children)[k];
                if (c.pid != pid) continue;
                c.exited = true;
                c.status = status;
                c.peak_rss_mb = static_cast<double>(usage.ru_maxrss) / 1024.0;  // KiB
                --running;
                if (!killed && Failed(status)) {
                    failed = static_cast<int>(k);
                    kill_running();
                }
            }
        } else if (pid < 0 && errno == ECHILD) {
            break;
        } else {
            if (!killed && Clock::now() > deadline) kill_running();
            std::this_thread::sleep_for(std::chrono::milliseconds(20));
        }
    }
    return failed;
}

/// The command of one robot process: `certislam-robot` beside this executable (the lean one: no
/// PCL, OpenVDB or front end mapped), else this executable's `robot` subcommand.
std::vector<std::string> RobotCommand() {
    const fs::path self = fs::read_symlink("/proc/self/exe");
    const fs::path lean = self.parent_path() / "certislam-robot";
    if (::access(lean.c_str(), X_OK) == 0) return {lean.string()};
    return {self.string(), "robot"};
}

std::string Slurp(const std::string& path) {
    std::ifstream in(path);
    std::stringstream text;
    text << in.rdbuf();
    return text.str();
}

/// The last line of a robot's stderr (its error message).
std::string LastLine(const std::string& text) {
    std::string line, last;
    std::istringstream in(text);
    while (std::getline(in, line)) {
        if (!line.empty()) last = line;
    }
    return last.empty() ? "(no message)" : last;
}

template <typename T>
T Field(const nlohmann::json& j, const char* key, int robot) {
    if (!j.contains(key)) {
        throw std::runtime_error("robot " + std::to_string(robot) + "'s report: " + key +
                                 ": missing");
    }
    return j.at(key).get<T>();
}

}  // namespace

actors::PoseGraphTeamResult MergeRobotReports(const std::vector<nlohmann::json>& reports) {
    actors::PoseGraphTeamResult r;
    if (reports.empty()) throw std::runtime_error("no robot reports");
    r.done = true;
    bool sync = true, in_rounds = true;
    for (const auto& j : reports) {
        const int robot = Field<int>(j, "robot", -1);
        r.done = r.done && Field<bool>(j, "certified", robot);
        const auto steps = Field<std::uint64_t>(j, "iterations", robot);
        r.iterations_by_robot[robot] = steps;
        r.iterations = std::max(r.iterations, steps);
        const auto bytes =
            Field<std::map<std::string, std::uint64_t>>(j, "bytes_sent_by_actor", robot);
        for (const auto& [actor, n] : bytes) {
            r.bytes_by_actor[actor] += n;
            r.bytes_by_robot[robot] += n;
            r.bytes_between_robots += n;
        }
        r.seconds = std::max(r.seconds, Field<double>(j, "seconds", robot));
        r.escapes += Field<int>(j, "escapes", robot);
        r.rejected_proposals += Field<std::uint64_t>(j, "rejected_proposals", robot);
        r.round_resends += Field<std::uint64_t>(j, "round_resends", robot);
        r.finish_dropped += Field<nlohmann::json>(j, "finish", robot).value("dropped", 0ull);
        const auto mode = Field<std::string>(j, "solver_mode", robot);
        sync = sync && mode == "synchronous";
        in_rounds = in_rounds && (mode == "synchronous" || mode == actors::kRoundsRunning);
        const auto plane = Field<nlohmann::json>(j, "out_of_plane", robot);
        r.out_of_plane_m = std::max(r.out_of_plane_m, plane.value("m", 0.0));
        r.out_of_plane_rad = std::max(r.out_of_plane_rad, plane.value("rad", 0.0));
    }
    r.solver_mode = actors::SolverMode(sync, in_rounds);
    const nlohmann::json& anchor = reports.front();
    const int id = Field<int>(anchor, "robot", -1);
    r.cost_offset = Field<double>(anchor, "cost_offset", id);
    r.certificate_rounds = Field<int>(anchor, "certificate_rounds", id);
    r.lanczos_steps = Field<std::uint64_t>(anchor, "lanczos_steps", id);
    r.certificate_seconds = Field<double>(anchor, "certificate_seconds", id);
    r.rank = Field<int>(anchor, "rank", id);
    r.restarts = Field<int>(anchor, "restarts", id);
    r.overlap_ends = Field<int>(anchor, "overlap_ends", id);
    r.fallbacks = Field<int>(anchor, "central_fallbacks", id);
    const auto finish = Field<nlohmann::json>(anchor, "finish", id);
    r.finish_status = finish.value("status", "");
    r.finish_steps = finish.value("steps", 0);
    r.finish_cg_iterations = finish.value("cg_iterations", 0);
    r.finish_exchanges = finish.value("exchanges", 0ull);
    r.finish_reductions = finish.value("reductions", 0ull);
    r.finish_seconds = finish.value("seconds", 0.0);
    if (anchor.contains("certificate_report")) {
        v1::CertificateReport report;
        const auto status = google::protobuf::util::JsonStringToMessage(
            anchor.at("certificate_report").dump(), &report);
        if (!status.ok()) {
            throw std::runtime_error("robot " + std::to_string(id) +
                                     "'s report: certificate_report: " + status.ToString());
        }
        r.report = report;
    }
    return r;
}

namespace {

/// One team of robot processes on the configuration written to `dir` (new tcp ports each time).
struct TeamRun {
    std::vector<Child> children;
    int failed = -1;  ///< the first robot that failed (WaitAll), or -1
    double wall = 0.0;
};

TeamRun RunTeam(const slam::Partition& partition, const DistributedSolveOptions& o,
                const fs::path& dir, const std::vector<std::string>& robot_command, int attempt) {
    const std::string config = (dir / "team.json").string();
    std::ofstream(config) << TeamConfigOf(o, partition, dir, attempt).dump(2) << "\n";
    const auto start = Clock::now();
    TeamRun run;
    run.children.resize(static_cast<size_t>(partition.num_robots()));
    for (int k = 0; k < partition.num_robots(); ++k) {
        Child& c = run.children[static_cast<size_t>(k)];
        c.robot = k;
        c.out = (dir / ("robot" + std::to_string(k) + ".json")).string();
        c.log = (dir / ("robot" + std::to_string(k) + ".log")).string();
        std::vector<std::string> args = robot_command;
        args.insert(args.end(), {config, "--id", std::to_string(k), "--json", "--timeout",
                                 std::to_string(o.timeout_s)});
        c.pid = Spawn(args, c.out, c.log);
    }
    run.failed = WaitAll(&run.children,
                         start + std::chrono::duration_cast<Clock::duration>(
                                     std::chrono::duration<double>(o.timeout_s + kGraceSeconds)));
    run.wall = std::chrono::duration<double>(Clock::now() - start).count();
    return run;
}

}  // namespace

int RunProcessSolve(const slam::PoseGraph& graph, const slam::Partition& partition,
                    const DistributedSolveOptions& o) {
    char templ[] = "/tmp/certislam-solve-XXXXXX";  // 0700: the ipc sockets' guard
    if (::mkdtemp(templ) == nullptr) throw std::runtime_error("cannot create a folder in /tmp");
    const fs::path dir = templ;
    const std::vector<std::string> robot_command = RobotCommand();
    TeamRun run;
    for (int attempt = 1;; ++attempt) {
        run = RunTeam(partition, o, dir, robot_command, attempt);
        // Another process bound a port between FreeBasePorts' check and the robot's bind.
        const bool port_taken =
            run.failed >= 0 && o.transport == "tcp" &&
            Slurp(run.children[static_cast<size_t>(run.failed)].log).find(kPortTaken) !=
                std::string::npos;
        if (!port_taken || attempt == kPortAttempts) break;
    }
    std::vector<nlohmann::json> reports;
    nlohmann::json rss = nlohmann::json::object();
    double peak = 0.0;
    for (size_t k = 0; k < run.children.size(); ++k) {
        const Child& c = run.children[run.failed >= 0 ? static_cast<size_t>(run.failed) : k];
        const int code = WIFEXITED(c.status) ? WEXITSTATUS(c.status) : -1;
        auto j = nlohmann::json::parse(Slurp(c.out), nullptr, false);
        if (run.failed >= 0 || Failed(c.status) || j.is_discarded()) {
            const std::string how =
                WIFSIGNALED(c.status)
                    ? std::string("was killed (") + ::strsignal(WTERMSIG(c.status)) + ")"
                    : "exited " + std::to_string(code);
            // A report that is not JSON is quoted: something else wrote to the robot's stdout.
            const std::string out = Slurp(c.out);
            const std::string report =
                j.is_discarded() && !Failed(c.status)
                    ? " (its report is not JSON: \"" +
                          out.substr(0, std::min<size_t>(out.find('\n'), 200)) + "\")"
                    : "";
            std::fprintf(stderr, "certislam solve: error: %s: robot %d (%s) %s: %s%s\n",
                         o.file.c_str(), c.robot, o.transport.c_str(), how.c_str(),
                         LastLine(Slurp(c.log)).c_str(), report.c_str());
            fs::remove_all(dir);
            return code == kExitBadInput ? kExitBadInput : kExitNotCertified;
        }
        reports.push_back(std::move(j));
        rss[std::to_string(c.robot)] = c.peak_rss_mb;
        peak = std::max(peak, c.peak_rss_mb);
    }
    fs::remove_all(dir);
    const actors::PoseGraphTeamResult result = MergeRobotReports(reports);
    nlohmann::json j = TeamResultJson(result, partition.num_robots(), o.transport);
    j["eigensolver"] = o.eigensolver;
    j["overlap"] = o.overlap >= 0 ? o.overlap : certify::TeamRoundsConfig{}.overlap_depth;
    j["finish_after_rounds"] =
        o.finish_after >= 0 ? o.finish_after : actors::SolverActorConfig{}.finish_after_rounds;
    j["peak_rss_mb"] = peak;  // the largest robot process
    j["peak_rss_mb_by_robot"] = rss;
    j["wall_seconds"] = run.wall;
    j["robot_executable"] =
        fs::path(robot_command.front())
            .filename()
            .string();  // processes started, graph read, solved, certified, exited
    return PrintDistributedReport(&j, result, graph, o);
}

}  // namespace certislam::bin
