// libFuzzer target of the g2o reader: arbitrary text must give a graph or a file:line error,
// never a crash, and an accepted graph holds only finite, bounded values and rotations.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <string>

#include "slam/io/g2o_io.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    using namespace certislam::slam;
    std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
    const PoseGraphReadResult r = ReadG2oStream(in, "fuzz.g2o");
    if (!r.ok()) {
        if (r.error.rfind("fuzz.g2o", 0) != 0) std::abort();  // errors name the file
        return 0;
    }
    for (const auto& e : r.graph.edges) {
        const bool finite =
            e.R.allFinite() && e.t.allFinite() && std::isfinite(e.kappa) && std::isfinite(e.tau);
        const auto d = e.R.rows();
        const double off = (e.R.transpose() * e.R - Eigen::MatrixXd::Identity(d, d)).norm();
        if (!finite || off > 1e-2 || !(e.kappa >= kMinWeight) || !(e.tau >= kMinWeight) ||
            e.i < 0 || e.j < 0 || e.i >= r.graph.n || e.j >= r.graph.n) {
            std::fprintf(stderr, "g2o fuzz: accepted an edge out of range\n");
            std::abort();
        }
    }
    return 0;
}
