// Reads a g2o file and solves it with the installed libraries; exit 0 when certified.
#include <cstdio>

#include "certify/pose_graph_solver.h"
#include "slam/io/g2o_io.h"

int main(int argc, char** argv) {
    if (argc != 2) {
        std::fprintf(stderr, "usage: consumer FILE.g2o\n");
        return 2;
    }
    const auto read = certislam::slam::ReadG2o(argv[1]);
    if (!read.ok()) {
        std::fprintf(stderr, "%s\n", read.error.c_str());
        return 1;
    }
    const auto result = certislam::certify::SolvePoseGraph(read.graph, {}, {});
    std::printf("%d poses, cost %.10g, %s\n", read.graph.n, result.cost,
                result.status == certislam::certify::PoseGraphSolverResult::Status::kCertified
                    ? "certified"
                    : "not certified");
    return result.status == certislam::certify::PoseGraphSolverResult::Status::kCertified ? 0 : 3;
}
