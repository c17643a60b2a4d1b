// libFuzzer target of the durable log reader (actors/durable_log.h): arbitrary bytes as a log file
// left by a crashed or foreign robot. Reading and the start-up check must never crash; what the
// check keeps must read back whole, under the same identity.
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>

#include "actors/durable_log.h"

namespace {

// The file the input is written to (one per fuzzing process).
const std::string& LogPath() {
    static const std::string path = (std::filesystem::temp_directory_path() /
                                     ("certislam_durable_log_fuzz_" + std::to_string(getpid())))
                                        .string();
    return path;
}

[[noreturn]] void Fail(const char* what) {
    std::fprintf(stderr, "durable log fuzz: %s\n", what);
    std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    using namespace certislam::actors;
    std::ofstream(LogPath(), std::ios::binary | std::ios::trunc)
        .write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
    const DurableLogRead read = ReadDurableLog(LogPath());
    if (read.good_bytes > size) Fail("more good bytes than the file holds");
    // The check against the identity the file claims: whatever it keeps must read back whole.
    try {
        const DurableLogCheck check =
            PrepareDurableLog(LogPath(), read.identity, StaleLogPolicy::kRefuse);
        const DurableLogRead again = ReadDurableLog(LogPath());
        if (again.torn_tail || again.bad_records != 0) Fail("a kept log still has bad records");
        if (static_cast<int>(again.messages.size()) != check.records) Fail("record count differs");
    } catch (const std::runtime_error&) {
        // Refused (another mission, no header, a corrupt record): the expected outcome.
    }
    std::filesystem::remove(LogPath());
    return 0;
}
