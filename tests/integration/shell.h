// Runs a real command line from a test and captures what it printed.
#pragma once

#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <string>

namespace certislam::testing {

/// What a command line did: its exit code (-1 when it did not exit normally) and its output.
struct ShellResult {
    int exit_code = -1;
    std::string out;
};

/// Runs `command` with /bin/sh and captures its stdout (add `2>&1` to capture stderr too).
inline ShellResult Shell(const std::string& command) {
    ShellResult result;
    std::FILE* pipe = popen(command.c_str(), "r");
    if (pipe == nullptr) return result;
    std::array<char, 4096> buffer{};
    size_t n = 0;
    while ((n = std::fread(buffer.data(), 1, buffer.size(), pipe)) > 0) {
        result.out.append(buffer.data(), n);
    }
    const int status = pclose(pipe);
    result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    return result;
}

}  // namespace certislam::testing
