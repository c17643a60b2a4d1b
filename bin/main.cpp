// Entry point of the `certislam` command: dispatches to the registered subcommands.
#include <cstdio>
#include <exception>
#include <string>
#include <vector>

#include "bin/command.h"

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

void PrintUsage(std::FILE* out) {
    std::fprintf(out, "usage: certislam <command> [options]   (certislam <command> --help)\n\n");
    for (const auto& [name, command] : certislam::bin::Registry()) {
        std::fprintf(out, "  %-10s %s\n", name.c_str(), command.summary.c_str());
    }
}

}  // namespace

int main(int argc, char** argv) {
    if (argc < 2) {
        PrintUsage(stderr);
        return 2;
    }
    const std::string name = argv[1];
    if (name == "-h" || name == "--help" || name == "help") {
        PrintUsage(stdout);
        return 0;
    }
    const auto& registry = certislam::bin::Registry();
    const auto it = registry.find(name);
    if (it == registry.end()) {
        std::fprintf(stderr, "certislam: unknown command '%s'\n\n", name.c_str());
        PrintUsage(stderr);
        return 2;
    }
    std::string program = "certislam " + name;
    std::vector<char*> args{program.data()};
    for (int i = 2; i < argc; ++i) args.push_back(argv[i]);
    try {
        return it->second.run(static_cast<int>(args.size()), args.data());
    } catch (const std::exception& e) {
        std::fprintf(stderr, "certislam %s: error: %s\n", name.c_str(), e.what());
        return 1;
    }
}
