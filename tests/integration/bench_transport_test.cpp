// `certislam bench transport --json` end to end with real processes: every transport row is
// present for each size, the shared-memory rows went through the Endpoint (a beyond-copy figure
// for ipc-shm), and no segment is left in /dev/shm afterwards.
#include <gtest/gtest.h>

#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <string>

#include "tests/integration/shell.h"

namespace certislam {
namespace {

using testing::Shell;

constexpr std::size_t kSmall = 1024;
constexpr std::size_t kLarge = std::size_t{1} << 20;  ///< over the 64 KiB shm threshold

/// Names under /dev/shm of the transport's default segment family ("certislam-<pid>-...").
std::set<std::string> Segments() {
    std::set<std::string> names;
    for (const auto& entry : std::filesystem::directory_iterator("/dev/shm")) {
        const std::string name = entry.path().filename().string();
        if (name.rfind("certislam-", 0) == 0) names.insert(name);
    }
    return names;
}

/// True when the process named in "certislam-<pid>-..." is alive.
bool CreatorAlive(const std::string& name) {
    const std::string pid = name.substr(10, name.find('-', 10) - 10);
    return std::filesystem::exists("/proc/" + pid);
}

TEST(BenchTransport, JsonHasEveryTransportAndSizeAndLeavesNoSegment) {
    const std::set<std::string> before = Segments();
    const auto result = Shell(std::string(CERTISLAM_BINARY) +
                              " bench transport --json --max-bytes 1048576 --scale 0.05");
    ASSERT_EQ(result.exit_code, 0) << result.out;
    const auto rows = nlohmann::json::parse(result.out);
    std::map<std::string, std::set<std::size_t>> sizes;
    for (const auto& row : rows) {
        const std::string transport = row.at("transport");
        sizes[transport].insert(row.at("bytes").get<std::size_t>());
        EXPECT_GT(row.at("latency_us").get<double>(), 0.0) << row.dump();
        EXPECT_GT(row.at("throughput_gbps").get<double>(), 0.0) << row.dump();
        EXPECT_EQ(row.contains("latency_beyond_copy_us"), transport == "ipc-shm") << row.dump();
    }
    const std::set<std::size_t> both = {kSmall, kLarge};
    for (const char* transport :
         {"memcpy", "inproc", "ipc-shm", "ipc-shm-loan", "ipc-socket", "tcp"}) {
        EXPECT_EQ(sizes[transport], both) << transport;
    }
    // Every segment the bench's (now exited) processes made is reclaimed; a new segment whose
    // creator still lives belongs to someone else's running program.
    for (const auto& name : Segments()) {
        if (before.count(name) > 0) continue;
        EXPECT_TRUE(CreatorAlive(name)) << name << " left behind";
    }
}

}  // namespace
}  // namespace certislam
