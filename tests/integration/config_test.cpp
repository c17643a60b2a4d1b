// `certislam config`: a misspelt key, a wrong type, a value out of range or a key of another
// source kind fails at start naming the file, the line and the key path; `config dump` prints a
// configuration that reads back; JSON files read as before.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "tests/integration/shell.h"

namespace certislam {
namespace {

using testing::Shell;

class Config : public ::testing::Test {
  protected:
    void SetUp() override {
        dir_ = std::filesystem::temp_directory_path() /
               ("certislam-config-" + std::to_string(getpid()));
        std::filesystem::create_directories(dir_);
    }
    void TearDown() override { std::filesystem::remove_all(dir_); }

    std::string Write(const std::string& name, const std::string& text) {
        std::ofstream(dir_ / name) << text;
        return (dir_ / name).string();
    }

    testing::ShellResult Check(const std::string& path) {
        return Shell(std::string(CERTISLAM_BINARY) + " config check " + path + " 2>&1");
    }

    std::filesystem::path dir_;
};

TEST_F(Config, MisspeltKeysFailNamingFileLineAndKeyPath) {
    const struct {
        const char* yaml;
        const char* error;
    } cases[] = {
        {"robots: [0, 1]\nsource: {kind: simulator}\nsolvr: {rank: 5}\n",
         "bad.yaml:3: solvr: unknown key (did you mean 'solver'?)"},
        {"robots: [0, 1]\nsource: {kind: simulator}\nmatcher:\n  query_strid: 3\n",
         "bad.yaml:4: matcher.query_strid: unknown key (did you mean 'query_stride'?)"},
        {"robots: [0, 1]\nsource:\n  kind: simulator\n  maxkeyframes: 60\n",
         "bad.yaml:4: source.maxkeyframes: unknown key (did you mean 'max_keyframes'?)"},
        {"robots: [0, 1]\nsource: {kind: simulator}\nsolver:\n  rank: five\n",
         "bad.yaml:4: solver.rank: must be an integer, not 'five'"},
        {"robots: [0, 1]\nsource: {kind: simulator}\nsolver: {rank: 100000}\n",
         "bad.yaml:3: solver.rank: 100000 is out of range [3, 64]"},
        {"robots: [0, 1]\nsource: {kind: simulator, path: x}\n",
         "bad.yaml:2: source.path: belongs to source.kind split, not simulator"},
        {"robots: [0, 1]\nsource: {kind: simulator}\nnetwork: {x: {base_port: 1}}\n",
         "bad.yaml:3: network.x: must be a robot id"},
        {"robots: [0, 1]\nsource: {kind: simulator}\nmapping: {team_map: everyone}\n",
         "bad.yaml:3: mapping.team_map: \"everyone\" is not one of anchor, all, none"},
        {"robots: [0, 1]\nsource: {kind: simulator}\ncertifier: {max_relative_bound: 1.5}\n",
         "bad.yaml:3: certifier.max_relative_bound: 1.5 is out of range (0, 1)"},
    };
    for (const auto& c : cases) {
        const auto result = Check(Write("bad.yaml", c.yaml));
        EXPECT_EQ(result.exit_code, 1) << c.yaml << result.out;
        EXPECT_NE(result.out.find(c.error), std::string::npos) << c.yaml << result.out;
    }
}

TEST_F(Config, JsonTypeErrorsNameTheKeyPath) {
    const auto result = Check(Write("bad.json", R"({"robots": [0, 1],
  "source": {"kind": "simulator"},
  "solver": {"rank": "5"}})"));
    EXPECT_EQ(result.exit_code, 1) << result.out;
    EXPECT_NE(result.out.find("bad.json:3: solver.rank: must be an integer, not the quoted"),
              std::string::npos)
        << result.out;
}

TEST_F(Config, EveryShippedConfigurationReads) {
    const std::filesystem::path configs =
        std::filesystem::path(CERTISLAM_SOURCE_DIR) / "deploy" / "configs";
    int read = 0;
    for (const auto& entry : std::filesystem::directory_iterator(configs)) {
        const auto result = Check(entry.path().string());
        EXPECT_EQ(result.exit_code, 0) << entry.path() << "\n" << result.out;
        ++read;
    }
    EXPECT_GE(read, 4);
}

TEST_F(Config, DumpReadsBackAndNamesEveryKeyOnce) {
    const auto dump = Shell(std::string(CERTISLAM_BINARY) + " config dump simulator");
    ASSERT_EQ(dump.exit_code, 0);
    EXPECT_NE(dump.out.find("  rank: 5 "), std::string::npos) << dump.out;
    EXPECT_NE(dump.out.find("# rank r of the Stiefel relaxation"), std::string::npos);
    const auto result = Check(Write("dump.yaml", dump.out));
    EXPECT_EQ(result.exit_code, 0) << result.out << dump.out;
    // A kind with per-robot paths: its dump has every key, and only the empty paths are missing.
    const auto kitti = Shell(std::string(CERTISLAM_BINARY) + " config dump kitti");
    ASSERT_EQ(kitti.exit_code, 0);
    const auto kitti_check = Check(Write("kitti.yaml", kitti.out));
    EXPECT_EQ(kitti_check.exit_code, 1);
    EXPECT_NE(kitti_check.out.find("source.sequences.0.folder: missing"), std::string::npos)
        << kitti_check.out;
    EXPECT_NE(Shell(std::string(CERTISLAM_BINARY) + " config dump teleport 2>&1").exit_code, 0);
}

}  // namespace
}  // namespace certislam
