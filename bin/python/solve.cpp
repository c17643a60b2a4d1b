// solve and certify for Python: the library calls of `certislam solve`, results with numpy poses.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl/filesystem.h>

#include <filesystem>
#include <string>

#include "bin/python/arrays.h"
#include "bin/python/bindings.h"
#include "bin/solve_output.h"
#include "certify/certificate.h"
#include "certify/pose_graph_solver.h"
#include "slam/backend/connection_laplacian.h"
#include "slam/io/g2o_io.h"
#include "slam/io/multirobot_io.h"

namespace certislam::python {
namespace {

using Status = certify::CertificateResult::Status;

/// What solve returns: the solver's result and its poses in the input's frame.
struct Solution {
    certify::PoseGraphSolverResult result;
    slam::PoseMatrix poses;  ///< rounded poses moved so that pose 0 is the input's pose 0
    int d = 3;
};

slam::PoseGraph Load(const py::object& source, bool* is_directory) {
    *is_directory = false;
    if (py::isinstance<slam::PoseGraph>(source)) return source.cast<slam::PoseGraph>();
    const auto path = source.cast<std::filesystem::path>();
    *is_directory = std::filesystem::is_directory(path);
    slam::PoseGraphReadResult read =
        *is_directory ? slam::ReadMultiRobotCsv(path) : slam::ReadG2o(path);
    if (!read.ok()) throw InputError(read.error);
    return std::move(read.graph);
}

void CheckConnected(const slam::PoseGraph& graph) {
    if (!slam::IsConnected(graph)) {
        throw InputError(
            "the pose graph is not connected (every pose must be reached from pose 0)");
    }
}

Solution Solve(const py::object& source, const std::string& method, const py::object& robots,
               int rank, bool robust) {
    bool is_directory = false;
    const slam::PoseGraph graph = Load(source, &is_directory);
    CheckConnected(graph);
    if (method != "rbcd" && method != "lm") {
        throw InputError("method = '" + method + "': must be 'rbcd' or 'lm'");
    }
    certify::PoseGraphSolverConfig config;
    config.method = method == "lm" ? certify::PoseGraphSolverConfig::Method::kLm
                                   : certify::PoseGraphSolverConfig::Method::kRbcd;
    config.robots = robots.is_none() ? (is_directory ? 0 : 1) : robots.cast<int>();
    config.rank = rank;
    config.robust = robust;
    Solution out;
    out.d = graph.d;
    try {
        py::gil_scoped_release release;
        out.result = certify::SolvePoseGraph(graph, config);
    } catch (const std::invalid_argument& e) {
        throw InputError(e.what());
    }
    out.poses = bin::InInputFrame(graph, out.result.poses);
    return out;
}

certify::CertificateResult Certify(const slam::PoseGraph& graph, const Array& poses) {
    CheckConnected(graph);
    const slam::PoseMatrix X = ArrayToPoses(poses, graph.d, "poses");
    if (X.cols() != (graph.d + 1) * graph.n) {
        throw InputError("certify: " + std::to_string(X.cols() / (graph.d + 1)) +
                         " poses for a graph of " + std::to_string(graph.n));
    }
    py::gil_scoped_release release;
    return certify::Certify(slam::ConnectionLaplacian(graph), X, graph.d);
}

void BindSolution(py::module_& m) {
    using R = certify::PoseGraphSolverResult;
    py::class_<Solution>(m, "Solution", "What solve found (SE-Sync's names for the bounds).")
        .def_property_readonly("poses",
                               [](const Solution& s) { return PosesToArray(s.poses, s.d); })
        .def_property_readonly("rotations",
                               [](const Solution& s) { return Rotations(s.poses, s.d); })
        .def_property_readonly("translations",
                               [](const Solution& s) { return Translations(s.poses, s.d); })
        .def_property_readonly("cost", [](const Solution& s) { return s.result.cost; })
        .def_property_readonly(
            "verdict", [](const Solution& s) { return certify::VerdictName(s.result.status); })
        .def_property_readonly(
            "certified", [](const Solution& s) { return s.result.status == R::Status::kCertified; })
        .def_property_readonly("reason", [](const Solution& s) { return s.result.reason; })
        .def_property_readonly("has_bound", [](const Solution& s) { return s.result.has_bound; })
        .def_property_readonly("lower_bound",
                               [](const Solution& s) { return s.result.lower_bound; })
        .def_property_readonly("suboptimality_bound",
                               [](const Solution& s) { return s.result.suboptimality_bound; })
        .def_property_readonly(
            "relative_bound",
            [](const Solution& s) { return s.result.relative_suboptimality_bound; })
        .def_property_readonly("rank", [](const Solution& s) { return s.result.rank; })
        .def_property_readonly("iterations", [](const Solution& s) { return s.result.iterations; })
        .def_property_readonly("edges_used", [](const Solution& s) { return s.result.edges_used; })
        .def_property_readonly("seconds", [](const Solution& s) { return s.result.seconds; })
        .def_property_readonly("graph", [](const Solution& s) { return s.result.solved_graph; })
        .def("__repr__", [](const Solution& s) {
            return std::string("<certislam.Solution ") + certify::VerdictName(s.result.status) +
                   " cost=" + std::to_string(s.result.cost) + ">";
        });
}

void BindCertificate(py::module_& m) {
    using C = certify::CertificateResult;
    py::class_<C>(m, "Certificate", "The dual certificate's verdict on given poses.")
        .def_property_readonly("verdict", [](const C& c) { return certify::VerdictName(c.status); })
        .def_property_readonly("certified",
                               [](const C& c) { return c.status == Status::kCertified; })
        .def_readonly("reason", &C::reason)
        .def_readonly("cost", &C::objective)
        .def_readonly("has_bound", &C::has_bound)
        .def_readonly("lower_bound", &C::lower_bound)
        .def_readonly("suboptimality_bound", &C::suboptimality_bound)
        .def_readonly("relative_bound", &C::relative_suboptimality_bound)
        .def_readonly("duality_gap", &C::duality_gap)
        .def_readonly("lambda_min", &C::lambda_min)
        .def_readonly("gradient_norm", &C::gradient_norm)
        .def_readonly("gradient_tolerance", &C::gradient_tolerance)
        .def("__repr__", [](const C& c) {
            return std::string("<certislam.Certificate ") + certify::VerdictName(c.status) + ">";
        });
}

}  // namespace

void BindSolve(py::module_& m) {
    BindSolution(m);
    BindCertificate(m);
    m.def("solve", &Solve, py::arg("source"), py::arg("method") = "rbcd",
          py::arg("robots") = py::none(), py::arg("rank") = 0, py::arg("robust") = false,
          "Solves a pose graph (a g2o path, a multi-robot CSV folder or a PoseGraph) as "
          "`certislam solve` does; poses come back in the input's frame (pose 0 as in its VERTEX "
          "line). robots: contiguous blocks (default 1; a CSV folder: its own robots).");
    m.def("certify", &Certify, py::arg("graph"), py::arg("poses"),
          "Certifies poses ((n, d+1, d+1), any common frame) of graph with the dual certificate.");
}

}  // namespace certislam::python
