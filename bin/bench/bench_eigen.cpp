// `certislam bench eigen FILE...`: the distributed smallest-eigenvalue check on g2o files at the
// solved optimum (or the chordal start), split into contiguous robots as `solve --robots N`
// does: Lanczos (DistributedMinEigenpair) beside block-Jacobi LOBPCG (DistributedLobpcg), with
// the centralised shift-invert value as the reference. Messages are counted as if distributed.
#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "bin/command.h"
#include "certify/certificate.h"
#include "certify/distributed/distributed_lanczos.h"
#include "certify/distributed/distributed_lobpcg.h"
#include "certify/min_eigenpair.h"
#include "certify/pipeline/team_rounds_in_memory.h"
#include "certify/pose_graph_solver.h"
#include "slam/backend/chordal.h"
#include "slam/backend/connection_laplacian.h"
#include "slam/core/graph_split.h"
#include "slam/core/partition.h"
#include "slam/io/g2o_io.h"

namespace certislam::bin {
namespace {

using Clock = std::chrono::steady_clock;

double SecondsSince(Clock::time_point start) {
    return std::chrono::duration<double>(Clock::now() - start).count();
}

struct Row {
    std::string file, solver;
    double lambda = 0.0, residual = 0.0, reference = 0.0, q_norm = 0.0, seconds = 0.0;
    double entries = 0.0, scalars = 0.0;
    int iterations = 0, products = 0, exchanges = 0, reductions = 0;
    bool converged = false;
};

void Print(const std::vector<Row>& rows, bool json) {
    if (json) {
        nlohmann::json j = nlohmann::json::array();
        for (const Row& r : rows) {
            j.push_back({{"file", r.file},
                         {"solver", r.solver},
                         {"converged", r.converged},
                         {"lambda_min", r.lambda},
                         {"central", r.reference},
                         {"q_norm", r.q_norm},
                         {"residual", r.residual},
                         {"iterations", r.iterations},
                         {"products", r.products},
                         {"exchanges", r.exchanges},
                         {"reductions", r.reductions},
                         {"entries", r.entries},
                         {"scalars_per_robot", r.scalars},
                         {"seconds", r.seconds}});
        }
        std::printf("%s\n", j.dump().c_str());
        return;
    }
    std::printf(
        "| file | solver | conv | lambda_min / ||Q|| | central / ||Q|| | residual / ||Q|| | "
        "iterations | S v products | exchanges | reductions | MB of v sent | scalars reduced "
        "per robot | wall s |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (const Row& r : rows) {
        std::printf(
            "| %s | %s | %s | %.3e | %.3e | %.1e | %d | %d | %d | %d | %.2f | %.0f | %.2f |\n",
            r.file.c_str(), r.solver.c_str(), r.converged ? "yes" : "no", r.lambda / r.q_norm,
            r.reference / r.q_norm, r.residual / r.q_norm, r.iterations, r.products, r.exchanges,
            r.reductions, 8e-6 * r.entries, r.scalars, r.seconds);
    }
}

/// The rounds (up to their max_rounds, converged or not), then the team's second-order finish
/// from there (certify/pipeline/team_finish.h), every message counted; prints both to stderr.
Eigen::MatrixXd FinishPoint(const slam::PoseGraph& graph, const slam::Partition& partition,
                            const certify::TeamRoundsConfig& rounds,
                            const certify::SolverConfig& solver,
                            const certify::TeamFinishConfig& finish) {
    auto start = Clock::now();
    certify::InMemoryTeam team =
        certify::RunTeamRoundsInMemory(slam::SplitGraph(graph, partition), solver, rounds);
    std::fprintf(stderr, "rounds: %llu swept (%s), %.2f s\n",
                 static_cast<unsigned long long>(team.rounds.front()),
                 team.AllConverged() ? "converged" : "not converged", SecondsSince(start));
    start = Clock::now();
    const certify::InMemoryFinish f = certify::RunTeamFinishInMemory(&team, finish);
    const certify::TeamFinishProgress& p = f.progress.front();
    std::fprintf(stderr,
                 "finish: %s%s, f %.12g, |grad| %.3e, %d trust-region steps (%d accepted), %d CG "
                 "iterations, %llu exchanges, %llu reductions, %.2f MB of vectors, %zu domain "
                 "edges, %.2f s\n",
                 f.AllConverged() ? "converged" : "not converged",
                 p.at_floor ? " at the floor" : "", p.cost, p.grad_norm, p.iterations, p.accepted,
                 p.tcg_iterations, static_cast<unsigned long long>(p.exchanges),
                 static_cast<unsigned long long>(p.reductions), 8e-6 * f.entries, f.edges,
                 SecondsSince(start));
    // The central check of the same X: the verdict the robots' certificate round would reach.
    Eigen::MatrixXd X = team.X();
    const certify::CertificateResult c =
        certify::Certify(slam::ConnectionLaplacian(graph), X, graph.d);
    std::fprintf(stderr, "certificate at the finish (central): %s, relative bound %.2e\n",
                 certify::VerdictName(c.status), c.relative_suboptimality_bound);
    return X;
}

/// The point S is built at: the solved optimum (rounded poses, rank d), the chordal start, the
/// last iterate of the robots' synchronous rounds (what `solve --distributed` certifies), or
/// the team's finish after them.
Eigen::MatrixXd PointOf(const slam::PoseGraph& graph, const std::string& point,
                        const slam::Partition& partition, const certify::TeamRoundsConfig& rounds,
                        const certify::SolverConfig& solver,
                        const certify::TeamFinishConfig& finish) {
    if (point == "chordal") return slam::LiftToRank(slam::ChordalInitialization(graph), 5);
    if (point == "finish") return FinishPoint(graph, partition, rounds, solver, finish);
    if (point == "rounds") {
        const auto start = Clock::now();
        const certify::InMemoryTeam team =
            certify::RunTeamRoundsInMemory(slam::SplitGraph(graph, partition), solver, rounds);
        if (!team.AllConverged()) {
            throw std::runtime_error("the rounds did not converge in " +
                                     std::to_string(rounds.max_rounds) + " rounds");
        }
        std::fprintf(stderr, "rounds: %llu swept, %d restarts, %.2f s\n",
                     static_cast<unsigned long long>(team.rounds.front()), team.restarts.front(),
                     SecondsSince(start));
        return team.X();
    }
    const certify::PoseGraphSolverResult solved = certify::SolvePoseGraph(graph);
    return solved.poses;
}

Row LanczosRow(Row r, const std::vector<certify::CertificateRows>& split, int dimension) {
    certify::LanczosSettings settings;
    settings.max_krylov = dimension;
    const auto start = Clock::now();
    const certify::DistributedEigenResult l = certify::DistributedMinEigenpair(split, settings);
    r.seconds = SecondsSince(start);
    r.solver = "Lanczos";
    r.converged = l.status == certify::DistributedEigenResult::Status::kConverged;
    r.lambda = l.lambda_min;
    r.residual = l.residual;
    r.iterations = l.steps;
    r.products = l.products;
    r.exchanges = l.vector_exchanges;
    r.reductions = l.scalar_reductions;
    r.entries = l.entries_exchanged;
    // setup 8, per step 1 + (step + 1), 3 at the end
    r.scalars = 8.0 + 3.0 + l.steps + 0.5 * l.steps * (l.steps + 3.0);
    return r;
}

Row LobpcgRow(Row r, const std::vector<certify::CertificateRows>& split,
              const certify::LobpcgSettings& settings, certify::LobpcgResult* out) {
    const auto start = Clock::now();
    const certify::LobpcgResult o = certify::DistributedLobpcg(split, settings);
    r.seconds = SecondsSince(start);
    r.solver = "LOBPCG m=" + std::to_string(settings.block_size);
    r.converged = o.status == certify::LobpcgResult::Status::kConverged;
    r.lambda = o.lambda_min;
    r.residual = o.residual;
    r.iterations = o.iterations;
    r.products = o.products;
    r.exchanges = o.vector_exchanges;
    r.reductions = o.scalar_reductions;
    r.entries = o.entries_exchanged;
    r.scalars = o.scalars_reduced;
    *out = o;
    return r;
}

void AddFinishOptions(CLI::App* app, certify::TeamFinishConfig* finish) {
    app->add_option("--finish-overlap", finish->overlap,
                    "--point finish: Schwarz domains' overlap in edges (0: block Jacobi)")
        ->check(CLI::Range(0, 8));
    app->add_option("--finish-tol", finish->rel_grad_tol,
                    "--point finish: the finish's relative gradient tolerance")
        ->check(CLI::PositiveNumber);
}

int RunEigenBench(int argc, char** argv) {
    CLI::App app{"Distributed smallest eigenvalue: Lanczos beside block-Jacobi LOBPCG"};
    std::vector<std::string> files;
    int robots = 5;
    std::string point = "optimum";
    bool json = false, skip_lanczos = false;
    certify::LobpcgSettings lobpcg;
    app.add_option("files", files, "g2o files")->required();
    app.add_option("--robots", robots, "contiguous robot blocks")->check(CLI::PositiveNumber);
    app.add_option("--point", point,
                   "optimum (solved, rounded), chordal (lifted to rank 5), rounds (the robots' "
                   "synchronous rounds' last iterate) or finish (the team's second-order finish "
                   "after at most --max-rounds rounds)")
        ->check(CLI::IsMember({"optimum", "chordal", "rounds", "finish"}));
    certify::TeamFinishConfig finish;
    AddFinishOptions(&app, &finish);
    certify::TeamRoundsConfig rounds;
    app.add_option("--rounds-tol", rounds.rel_grad_tol,
                   "--point rounds: the rounds' relative gradient tolerance");
    app.add_option("--max-rounds", rounds.max_rounds, "--point rounds: rounds before giving up")
        ->check(CLI::PositiveNumber);
    app.add_option("--overlap", rounds.overlap_depth,
                   "--point rounds: overlapping sweeps' depth in edges (0: none)")
        ->check(CLI::Range(0, 16));
    certify::SolverConfig solver;
    app.add_option("--block-steps", solver.rbcd.block_max_rtr_iterations,
                   "--point rounds: trust-region steps per block update at most")
        ->check(CLI::PositiveNumber);
    app.add_option("--block-reduction", solver.rbcd.block_grad_reduction,
                   "--point rounds: a block update stops when its gradient fell by this factor")
        ->check(CLI::Range(1e-12, 0.999));
    app.add_option("--tcg-floor", solver.rbcd.tcg_residual_floor,
                   "--point rounds: truncated CG stops at this * the block's gradient tolerance")
        ->check(CLI::Range(0.0, 0.999));
    app.add_option("--tcg-max", solver.rbcd.max_tcg_iterations,
                   "--point rounds: truncated-CG iterations per trust-region step at most")
        ->check(CLI::PositiveNumber);
    app.add_option("--block", lobpcg.block_size, "LOBPCG block size")->check(CLI::Range(1, 16));
    app.add_option("--drop", lobpcg.drop_tolerance, "LOBPCG Gram drop tolerance");
    app.add_option("--shift", lobpcg.shift_relative, "LOBPCG preconditioner shift (relative)");
    app.add_flag("--skip-lanczos", skip_lanczos, "LOBPCG only");
    app.add_flag("--json", json, "machine-readable output");
    CLI11_PARSE(app, argc, argv);

    std::vector<Row> rows;
    for (const std::string& file : files) {
        const slam::PoseGraphReadResult read = slam::ReadG2o(file);
        if (!read.ok()) throw std::runtime_error(read.error);
        const slam::PoseGraph graph = slam::LiftPlanar(read.graph);  // the robots solve in 3D
        const slam::Partition partition = slam::ContiguousPartition(graph.n, robots);
        const Eigen::MatrixXd X = PointOf(graph, point, partition, rounds, solver, finish);
        const Eigen::SparseMatrix<double> Q = slam::ConnectionLaplacian(graph);
        const Eigen::SparseMatrix<double> S =
            certify::CertificateMatrix(Q, certify::LambdaBlocks(Q, X, graph.d), graph.d);
        std::vector<certify::CertificateRows> split;
        split.reserve(static_cast<size_t>(robots));
        for (int k = 0; k < robots; ++k) {
            split.push_back(certify::MakeCertificateRows(Q, X, graph.d, partition, k));
        }
        Row base;
        base.file = file.substr(file.find_last_of('/') + 1);
        base.q_norm = certify::NormUpperBound(Q);
        auto start = Clock::now();
        base.reference = certify::SmallestEigenpair(S).lambda;
        Row central = base;
        central.solver = "central shift-invert";
        central.lambda = base.reference;
        central.converged = true;
        central.seconds = SecondsSince(start);
        rows.push_back(central);
        if (!skip_lanczos) rows.push_back(LanczosRow(base, split, static_cast<int>(Q.rows())));
        certify::LobpcgResult o;
        rows.push_back(LobpcgRow(base, split, lobpcg, &o));
        if (!json) {
            std::fprintf(stderr, "%s: restarts %d, largest shift %.2e, ||S||_inf %.4e\n",
                         base.file.c_str(), o.restarts, o.max_shift, o.scale);
        }
    }
    Print(rows, json);
    return 0;
}

const BenchRegistrar kBench{"eigen", "distributed smallest eigenvalue: Lanczos beside LOBPCG",
                            RunEigenBench};

}  // namespace
}  // namespace certislam::bin
