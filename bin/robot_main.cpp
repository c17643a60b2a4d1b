// `certislam-robot CONFIG --id K [--json]`: one back-end-only robot (pose-graph source, RBCD
// solver and certifier actors) as a process of its own, with `certislam robot`'s options,
// configuration and errors (bin/robot_command.h), in an executable that links no PCL, OpenVDB,
// front end or mapping: `solve --distributed --transport ipc|tcp` starts one per robot.
#include <malloc.h>

#include <CLI/CLI.hpp>
#include <string>

#include "bin/command.h"
#include "bin/robot_command.h"
#include "bin/version.h"

namespace {

/// Caps glibc's heap at two arenas (its default is 8 per core: each actor thread that allocates
/// gets one, whose freed pages stay resident) and serves blocks of 256 KiB and more from mmap
/// (returned on free; glibc's default threshold grows to 32 MiB after the first such free, after
/// which the certificate's factorisations fragment the arenas); BENCHMARKS.md, "Robots as
/// processes", has the effect on peak RSS.
void TuneMalloc() {
    mallopt(M_ARENA_MAX, 2);
    mallopt(M_MMAP_THRESHOLD, 256 * 1024);
}

}  // namespace

int main(int argc, char** argv) {
    using namespace certislam::bin;  // NOLINT(google-build-using-namespace): a thin main
    TuneMalloc();
    CLI::App app{
        "One back-end-only robot of a configuration (pose_graph source); peers over tcp "
        "or ipc (CURVE with keys)"};
    app.name("certislam-robot");
    app.set_version_flag("--version",
                         std::string("certislam-robot ") + kVersion + " (" + kGitDescribe + ")");
    RobotCommandOptions options;
    AddRobotCommandOptions(app, &options);
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        return app.exit(e) == 0 ? kExitDone : kExitUsage;
    }
    return RunRobotCommand(options, "certislam-robot", nullptr);
}
