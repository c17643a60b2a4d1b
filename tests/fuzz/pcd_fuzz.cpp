// libFuzzer target of the PCD reader (header, ascii, binary, binary_compressed): arbitrary bytes
// must give a cloud or a "file[:line]: rule" error, never a crash or an allocation beyond the
// input's bound (libFuzzer's -rss_limit_mb catches the latter).
#include <cstdint>
#include <cstdlib>
#include <vector>

#include "slam/io/cloud_io_pcd.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    using namespace certislam::slam;
    const std::vector<unsigned char> bytes(data, data + size);
    const CloudReadResult r = cloud_io_internal::ParsePcd("fuzz.pcd", bytes);
    if (!r.ok() && r.error.rfind("fuzz.pcd", 0) != 0) std::abort();  // errors name the file
    if (!r.ok() && !r.cloud.empty()) std::abort();
    for (const auto& p : r.cloud) {
        if (!p.allFinite()) std::abort();
    }
    return 0;
}
