// libFuzzer target of a peer's submap bytes (slam::DeserializeSubmap, after the MapUpdate's zstd
// frame is opened): arbitrary bytes give a submap or an error, never a crash; an accepted submap
// has a rigid anchor pose and serializes to bytes that parse again. Seeds: fuzz_submap_seeds.
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>

#include "slam/mapping/submap.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    using namespace certislam::slam;
    std::string error;
    const auto submap =
        DeserializeSubmap(std::string_view(reinterpret_cast<const char*>(data), size), &error);
    if (!submap) {
        if (error.empty()) std::abort();  // a refusal says why
        return 0;
    }
    const Eigen::Matrix3d R = submap->T_world_submap.linear();
    if (!R.allFinite() || !submap->T_world_submap.translation().allFinite() ||
        (R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > 1e-3) {
        std::fprintf(stderr, "submap fuzz: accepted a non-rigid anchor pose\n");
        std::abort();
    }
    std::string again;
    if (!DeserializeSubmap(SerializeSubmap(*submap), &again)) {
        std::fprintf(stderr, "submap fuzz: an accepted submap does not round-trip: %s\n",
                     again.c_str());
        std::abort();
    }
    return 0;
}
