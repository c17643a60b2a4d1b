// `certislam config dump [KIND] [--markdown]`: a complete team configuration with every default
// and a comment per key, or the README's reference table; `config check FILE` reads a file.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <string>

#include "bin/command.h"
#include "bin/config/config_keys.h"
#include "bin/config/team_config.h"

namespace certislam::bin {

namespace {

int RunConfig(int argc, char** argv) {
    CLI::App app{"Prints the configuration keys of `run` and `robot`"};
    app.name("certislam config");
    app.require_subcommand(1);
    auto* dump = app.add_subcommand(
        "dump", "print a complete configuration (YAML) with every default and a comment per key");
    std::string kind = "simulator";
    bool markdown = false;
    std::string kinds;
    for (const auto& k : SourceKindNames()) kinds += (kinds.empty() ? "" : ", ") + k;
    dump->add_option("kind", kind, "source kind: " + kinds)->capture_default_str();
    dump->add_flag("--markdown", markdown, "print the reference table of every key (Markdown)");
    auto* check = app.add_subcommand(
        "check",
        "read a configuration file as `run` and `robot` do; exit 1 naming the first error");
    std::string file;
    check->add_option("file", file, "the configuration (YAML or JSON)")->required();
    CLI11_PARSE(app, argc, argv);
    if (check->parsed()) {
        const TeamConfig config = LoadTeamConfig(file);
        std::printf("%s: ok (%zu robots)\n", file.c_str(), config.robots.size());
        return 0;
    }
    const std::string text = markdown ? DumpConfigMarkdown() : DumpConfigYaml(kind);
    std::fputs(text.c_str(), stdout);
    return 0;
}

const Registrar kRegistrar{"config", "print a complete configuration or the key reference",
                           RunConfig};

}  // namespace

}  // namespace certislam::bin
