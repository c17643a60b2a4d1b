// Entry point of the `certislam` command: CLI11 dispatches to the registered subcommands, each of
// which parses its own options.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <exception>
#include <string>
#include <vector>

#include "bin/command.h"
#include "bin/version.h"

namespace certislam::bin {

std::map<std::string, Command>& Registry() {
    static std::map<std::string, Command> registry;
    return registry;
}

Registrar::Registrar(const std::string& name, std::string summary, CommandFn run) {
    Registry()[name] = Command{std::move(summary), std::move(run)};
}

}  // namespace certislam::bin

namespace {

constexpr const char* kExitCodes =
    "Exit codes: 0 done (certified where there is a certificate), 1 bad input or configuration,\n"
    "2 usage error, 3 finished but not certified (or timed out).\n"
    "JSON on stdout only with --json (every object has schema_version); `certislam COMMAND "
    "--help`.";

/// CLI11's own parse-error codes (its ExitCodes from IncorrectConstruction to BaseClass).
bool IsCli11ParseError(int code) { return code >= 100 && code <= 127; }

}  // namespace

int main(int argc, char** argv) {
    using certislam::bin::Registry;
    CLI::App app{"certislam: decentralized multi-robot LiDAR SLAM, certifiably optimal back end"};
    app.name("certislam");
    app.set_version_flag("--version", std::string("certislam ") + certislam::bin::kVersion + " (" +
                                          certislam::bin::kGitDescribe + ")");
    app.footer(kExitCodes);
    app.require_subcommand(1, 1);
    for (const auto& [name, command] : Registry()) {
        CLI::App* sub = app.add_subcommand(name, command.summary);
        sub->prefix_command();  // the command parses the rest itself
        sub->set_help_flag();   // so `certislam NAME --help` reaches the command's own help
    }
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        return app.exit(e) == 0 ? 0 : 2;
    }
    CLI::App* sub = app.get_subcommands().front();
    const std::string name = sub->get_name();
    std::string program = "certislam " + name;
    std::vector<std::string> rest = sub->remaining();
    std::vector<char*> args{program.data()};
    for (auto& arg : rest) args.push_back(arg.data());
    try {
        const int code = Registry().at(name).run(static_cast<int>(args.size()), args.data());
        return IsCli11ParseError(code) ? 2 : code;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "certislam %s: error: %s\n", name.c_str(), e.what());
        return 1;
    }
}
