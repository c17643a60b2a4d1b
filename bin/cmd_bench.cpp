// `certislam bench <name>`: runs one registered benchmark (each lives in its own bench_*.cpp).
#include <cstdio>
#include <string>
#include <vector>

#include "bin/command.h"

namespace certislam::bin {

std::map<std::string, Command>& BenchRegistry() {
    static std::map<std::string, Command> registry;
    return registry;
}

BenchRegistrar::BenchRegistrar(const std::string& name, std::string summary, CommandFn run) {
    BenchRegistry()[name] = Command{std::move(summary), std::move(run)};
}

namespace {

void PrintBenchUsage(std::FILE* out) {
    std::fprintf(out, "usage: certislam bench <name> [--json] [options]\n\n");
    for (const auto& [name, bench] : BenchRegistry()) {
        std::fprintf(out, "  %-10s %s\n", name.c_str(), bench.summary.c_str());
    }
}

int RunBench(int argc, char** argv) {
    if (argc < 2) {
        PrintBenchUsage(stderr);
        return 2;
    }
    const std::string name = argv[1];
    if (name == "-h" || name == "--help") {
        PrintBenchUsage(stdout);
        return 0;
    }
    const auto it = BenchRegistry().find(name);
    if (it == BenchRegistry().end()) {
        std::fprintf(stderr, "certislam bench: unknown benchmark '%s'\n\n", name.c_str());
        PrintBenchUsage(stderr);
        return 2;
    }
    std::string program = "certislam bench " + name;
    std::vector<char*> args{program.data()};
    for (int i = 2; i < argc; ++i) args.push_back(argv[i]);
    return it->second.run(static_cast<int>(args.size()), args.data());
}

const Registrar kRegistrar{"bench", "run a benchmark (certislam bench --help lists them)",
                           RunBench};

}  // namespace
}  // namespace certislam::bin
