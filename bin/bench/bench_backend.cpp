// `certislam bench backend [FILE]`: the back end's per-iteration kernels on one g2o file (default
// parking-garage): V Q, the tangent projection and the finish's preconditioner, each beside the
// code it replaced or a reference, as milliseconds per call (median of batches).
#include <CLI/CLI.hpp>
#include <Eigen/CholmodSupport>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <functional>
#include <nlohmann/json.hpp>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "bin/command.h"
#include "slam/backend/connection_laplacian.h"
#include "slam/backend/schwarz_preconditioner.h"
#include "slam/backend/sparse_product.h"
#include "slam/backend/stiefel.h"
#include "slam/core/partition.h"
#include "slam/io/g2o_io.h"

namespace certislam::bin {
namespace {

using Clock = std::chrono::steady_clock;

// Median over `batches` of the mean time of `calls` calls, in ms.
double MedianMs(const std::function<void()>& body, int batches, int calls) {
    std::vector<double> ms;
    for (int b = 0; b < batches; ++b) {
        const auto start = Clock::now();
        for (int c = 0; c < calls; ++c) body();
        ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - start).count() /
                     calls);
    }
    std::nth_element(ms.begin(), ms.begin() + batches / 2, ms.end());
    return ms[batches / 2];
}

// The tangent projection as it was written before the per-pose loops (9e4c7a2: Eigen's products
// on r x d blocks, d x d results without heap allocation), kept here as the baseline.
Eigen::MatrixXd ProjectWithEigenBlocks(const Eigen::MatrixXd& X, const Eigen::MatrixXd& V, int d) {
    using Small = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 3, 3>;
    Eigen::MatrixXd out = V;
    for (int c = 0; c < X.cols(); c += d + 1) {
        const auto Y = X.middleCols(c, d);
        const Small S = Y.transpose() * V.middleCols(c, d);
        const Small sym = 0.5 * (S + S.transpose());
        out.middleCols(c, d).noalias() -= Y * sym;
    }
    return out;
}

struct Row {
    std::string kernel;
    std::string variant;
    double ms;
    double ratio;  // to the kernel's first variant
};

void PrintRows(const std::vector<Row>& rows, bool json, const std::string& file, int rank,
               int robots, int poses, const Eigen::SparseMatrix<double>& Q) {
    if (json) {
        nlohmann::json j{{"file", file},
                         {"rank", rank},
                         {"robots", robots},
                         {"poses", poses},
                         {"q_nonzeros", Q.nonZeros()}};
        for (const Row& r : rows) {
            j["kernels"].push_back(
                {{"kernel", r.kernel}, {"variant", r.variant}, {"ms", r.ms}, {"ratio", r.ratio}});
        }
        std::printf("%s\n", j.dump().c_str());
        return;
    }
    std::printf("%s: %d poses, Q %ld x %ld with %ld nonzeros, r = %d, %d robots\n", file.c_str(),
                poses, static_cast<long>(Q.rows()), static_cast<long>(Q.cols()),
                static_cast<long>(Q.nonZeros()), rank, robots);
    std::printf("| kernel | variant | ms per call | ratio to the first |\n|---|---|---|---|\n");
    for (const Row& r : rows) {
        std::printf("| %s | %s | %.3f | %.2f |\n", r.kernel.c_str(), r.variant.c_str(), r.ms,
                    r.ratio);
    }
}

int RunBackendBench(int argc, char** argv) {
    CLI::App app{"Times the back end's per-iteration kernels on a g2o file"};
    std::string file = "../shared/data/g2o/parking-garage.g2o";  // from the repository root
    int rank = 3;
    int robots = 5;
    int batches = 7;
    bool json = false;
    app.add_option("file", file, "g2o file (default: parking-garage in ../shared/data)");
    app.add_option("--rank", rank, "relaxation rank r (rows of V)")->check(CLI::Range(1, 16));
    app.add_option("--robots", robots, "contiguous robot blocks of the Schwarz preconditioner")
        ->check(CLI::PositiveNumber);
    app.add_option("--batches", batches, "timed batches per kernel (median)")
        ->check(CLI::Range(1, 101));
    app.add_flag("--json", json, "machine-readable output");
    CLI11_PARSE(app, argc, argv);

    const slam::PoseGraphReadResult read = slam::ReadG2o(file);
    if (!read.ok()) throw std::runtime_error(read.error);
    const int d = read.graph.d;
    if (rank < d) throw std::invalid_argument("--rank " + std::to_string(rank) + ": must be >= d");
    if (robots > read.graph.n) throw std::invalid_argument("--robots: more robots than poses");
    const Eigen::SparseMatrix<double> Q = slam::ConnectionLaplacian(read.graph);
    std::mt19937 rng(1);
    std::normal_distribution<double> normal;
    Eigen::MatrixXd V(rank, Q.cols());
    for (Eigen::Index i = 0; i < V.size(); ++i) V.data()[i] = normal(rng);
    const Eigen::MatrixXd X = slam::ProjectToManifold(V.reverse(), d);
    Eigen::MatrixXd out;
    const int calls = std::max(1, static_cast<int>(2e7 / static_cast<double>(Q.nonZeros())));

    std::vector<Row> rows;
    size_t first = 0;  // the current kernel's first row
    auto add = [&](const std::string& kernel, const std::string& variant,
                   const std::function<void()>& body) {
        const double ms = MedianMs(body, batches, calls);
        if (rows.empty() || rows.back().kernel != kernel) first = rows.size();
        rows.push_back({kernel, variant, ms, rows.size() == first ? 1.0 : ms / rows[first].ms});
    };
    add("V Q", "Eigen (Q V^T)^T", [&] { out = (Q * Eigen::MatrixXd(V.transpose())).transpose(); });
    add("V Q", "Eigen V * Q", [&] { out = V * Q; });
    add("V Q", "DenseTimesSparse", [&] { out = slam::DenseTimesSparse(V, Q); });
    add("tangent projection", "Eigen r x d blocks", [&] { out = ProjectWithEigenBlocks(X, V, d); });
    add("tangent projection", "ProjectToTangent", [&] { out = slam::ProjectToTangent(X, V, d); });

    const slam::Partition partition = slam::ContiguousPartition(read.graph.n, robots);
    const double regulariser = 1e-8;
    slam::SchwarzPreconditioner jacobi(Q, d, partition, 0, 1, regulariser);
    slam::SchwarzPreconditioner schwarz(Q, d, partition, 2, 1, regulariser);
    schwarz.ReportCgIterations(2);  // escalates to overlap 2
    Eigen::SparseMatrix<double> Q_shifted = Q;
    const double shift = regulariser * Q.diagonal().maxCoeff();
    for (int i = 0; i < Q.rows(); ++i) Q_shifted.coeffRef(i, i) += shift;
    Eigen::CholmodDecomposition<Eigen::SparseMatrix<double>, Eigen::Lower> full;
    full.setMode(Eigen::CholmodSimplicialLLt);
    full.compute(Q_shifted);
    if (full.info() != Eigen::Success) throw std::runtime_error("Q + shift did not factorise");
    const Eigen::MatrixXd B = V.transpose();
    add("preconditioner", "full Q Cholesky (centralised)", [&] { out = full.solve(B); });
    add("preconditioner", "block Jacobi (overlap 0)", [&] { out = jacobi.Solve(B); });
    add("preconditioner", "Schwarz overlap 2", [&] { out = schwarz.Solve(B); });

    PrintRows(rows, json, file, rank, robots, read.graph.n, Q);
    return 0;
}

const BenchRegistrar kBench{"backend", "per-iteration kernels of the back end on a g2o file",
                            RunBackendBench};

}  // namespace
}  // namespace certislam::bin
