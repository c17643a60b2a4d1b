// A scratch folder of its own for each test: ctest runs every test of a file as its own
// process, in parallel, so a folder shared by a file's tests races (one writes while another
// reads).
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <system_error>
#include <vector>

namespace certislam::testing {

/// Removes the scratch folders at exit when every test of the process passed (kept to inspect).
struct ScratchCleaner {
    std::vector<std::filesystem::path> dirs;
    ~ScratchCleaner() {
        if (!::testing::UnitTest::GetInstance()->Passed()) return;
        std::error_code ignored;
        for (const auto& dir : dirs) std::filesystem::remove_all(dir, ignored);
    }
};

/// temp/certislam_<suite>.<test>.<pid>/, created; parameterised names keep their "/N" as "_N".
inline std::filesystem::path ScratchDir() {
    static ScratchCleaner cleaner;
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::string name = std::string("certislam_") + (info ? info->test_suite_name() : "none") + "." +
                       (info ? info->name() : "none") + "." + std::to_string(getpid());
    for (char& c : name) {
        if (c == '/') c = '_';
    }
    const auto dir = std::filesystem::temp_directory_path() / name;
    std::filesystem::create_directories(dir);
    if (cleaner.dirs.empty() || cleaner.dirs.back() != dir) cleaner.dirs.push_back(dir);
    return dir;
}

/// Writes `text` (bytes as they are) to ScratchDir() / name; returns the path.
inline std::string WriteScratch(const std::string& name, const std::string& text) {
    const std::string path = (ScratchDir() / name).string();
    std::ofstream(path, std::ios::binary) << text;
    return path;
}

}  // namespace certislam::testing
