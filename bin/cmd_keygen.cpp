// `certislam keygen [--out PREFIX] [--force] [--json]`: writes a CURVE key pair for one robot;
// an existing key is kept unless --force.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "bin/command.h"
#include "transport/curve.h"

namespace certislam::bin {

namespace {

int RunKeygen(int argc, char** argv) {
    CLI::App app{
        "Writes a CURVE key pair: PREFIX.pub (share it; allow-lists name it) and "
        "PREFIX.key (secret, mode 0600)"};
    app.name("certislam keygen");
    std::string prefix = "robot";
    bool json = false;
    bool force = false;
    app.option_defaults()->always_capture_default();
    app.add_option("--out", prefix, "path prefix of the two files");
    app.add_flag("--force", force, "overwrite existing PREFIX.pub / PREFIX.key");
    app.add_flag("--json", json, "print the file names and public key as JSON");
    CLI11_PARSE(app, argc, argv);

    for (const std::string& path : {prefix + ".pub", prefix + ".key"}) {
        if (!force && std::filesystem::exists(path)) {
            std::fprintf(stderr,
                         "certislam keygen: %s exists: not overwriting a key (--force to replace "
                         "it)\n",
                         path.c_str());
            return kExitBadInput;
        }
    }
    const transport::KeyPair keys = transport::GenerateKeyPair();
    transport::SaveKeyPair(keys, prefix);
    if (json) {
        nlohmann::json out{{"schema_version", kSchemaVersion},
                           {"public_key_file", prefix + ".pub"},
                           {"secret_key_file", prefix + ".key"},
                           {"public_z85", keys.public_z85}};
        std::printf("%s\n", out.dump(2).c_str());
    } else {
        std::printf("public key %s\nwrote %s.pub and %s.key\n", keys.public_z85.c_str(),
                    prefix.c_str(), prefix.c_str());
    }
    return 0;
}

const Registrar kRegistrar{"keygen", "write a CURVE key pair for a robot (PREFIX.pub, PREFIX.key)",
                           RunKeygen};

}  // namespace

}  // namespace certislam::bin
