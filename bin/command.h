// The subcommand registry of the `certislam` command: each cmd_*.cpp registers one subcommand.
#pragma once

#include <functional>
#include <map>
#include <string>
#include <vector>

namespace certislam::bin {

/// Version of every JSON object the command prints or writes (bump on an incompatible change).
inline constexpr int kSchemaVersion = 1;

/// Exit codes of every subcommand (documented in `certislam --help` and the README).
enum ExitCode : int {
    kExitDone = 0,          ///< done (certified where there is a certificate)
    kExitBadInput = 1,      ///< bad input file or configuration
    kExitUsage = 2,         ///< bad command line
    kExitNotCertified = 3,  ///< finished but not certified (or timed out)
};

/// A subcommand's entry point: receives its own arguments (argv[0] is "certislam <name>") and
/// returns the process exit code.
using CommandFn = std::function<int(int argc, char** argv)>;

/// One registered subcommand.
struct Command {
    std::string summary;  ///< one line shown by `certislam --help`
    CommandFn run;        ///< entry point
};

/// All subcommands by name.
std::map<std::string, Command>& Registry();

/// Registers a subcommand at static-initialisation time: `static Registrar r{"solve", ...};`.
struct Registrar {
    Registrar(const std::string& name, std::string summary, CommandFn run);
};

/// All benchmarks of `certislam bench <name>` by name (same shape as subcommands).
std::map<std::string, Command>& BenchRegistry();

/// Registers a benchmark: `static BenchRegistrar r{"transport", "...", RunTransportBench};`.
struct BenchRegistrar {
    BenchRegistrar(const std::string& name, std::string summary, CommandFn run);
};

}  // namespace certislam::bin
