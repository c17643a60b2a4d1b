// PoseGraph for Python (built from numpy or read from g2o) and g2o writing.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl/filesystem.h>

#include <algorithm>
#include <filesystem>
#include <string>

#include "bin/python/arrays.h"
#include "bin/python/bindings.h"
#include "slam/io/g2o_io.h"

namespace certislam::python {
namespace {

void CheckDimension(int d) {
    if (d != 2 && d != 3) throw InputError("d = " + std::to_string(d) + ": must be 2 or 3");
}

/// Grows the graph to n poses (robot 0, index g: the readers' ids for a single robot).
void Resize(slam::PoseGraph* graph, int n) {
    if (n <= graph->n) return;
    graph->n = n;
    graph->ids.resize(n);
    for (int g = 0; g < n; ++g) graph->ids[g] = {0, g};
    graph->initial_guess.reset();  // no longer one guess per pose
}

void AddEdge(slam::PoseGraph* graph, int i, int j, const Array& T, double kappa, double tau) {
    const int d = graph->d;
    if (i < 0 || j < 0) throw InputError("add_edge: pose indices must be >= 0");
    if (T.ndim() != 2) throw InputError("add_edge: T must be a (d+1, d+1) array");
    Array one(std::vector<py::ssize_t>{1, T.shape(0), T.shape(1)});
    std::copy(T.data(), T.data() + T.size(), one.mutable_data());
    const slam::PoseMatrix P = ArrayToPoses(one, d, "add_edge T");
    slam::RelativePoseMeasurement e;
    e.i = i;
    e.j = j;
    e.R = P.leftCols(d);
    e.t = P.col(d);
    e.kappa = kappa;
    e.tau = tau;
    if (const std::string why = slam::CheckMeasurementRange(e.t, kappa, tau); !why.empty()) {
        throw InputError("add_edge(" + std::to_string(i) + ", " + std::to_string(j) + "): " + why);
    }
    Resize(graph, std::max({graph->n, i + 1, j + 1}));
    graph->edges.push_back(std::move(e));
}

py::object InitialGuess(const slam::PoseGraph& graph) {
    if (!graph.initial_guess) return py::none();
    return PosesToArray(*graph.initial_guess, graph.d);
}

void SetInitialGuess(slam::PoseGraph* graph, const py::object& poses) {
    if (poses.is_none()) {
        graph->initial_guess.reset();
        return;
    }
    const slam::PoseMatrix P = ArrayToPoses(poses.cast<Array>(), graph->d, "initial_guess");
    if (P.cols() != (graph->d + 1) * graph->n) {
        throw InputError("initial_guess: " + std::to_string(P.cols() / (graph->d + 1)) +
                         " poses for a graph of " + std::to_string(graph->n));
    }
    graph->initial_guess = P;
}

/// The edges as arrays: indices (m, 2), transforms (m, d+1, d+1), kappa (m,), tau (m,).
py::dict Edges(const slam::PoseGraph& graph) {
    const int d = graph.d;
    const auto m = static_cast<py::ssize_t>(graph.edges.size());
    py::array_t<int> indices(std::vector<py::ssize_t>{m, 2});
    Array kappa(std::vector<py::ssize_t>{m}), tau(std::vector<py::ssize_t>{m});
    slam::PoseMatrix T(d, (d + 1) * m);
    auto idx = indices.mutable_unchecked<2>();
    for (py::ssize_t k = 0; k < m; ++k) {
        const auto& e = graph.edges[k];
        idx(k, 0) = e.i;
        idx(k, 1) = e.j;
        kappa.mutable_at(k) = e.kappa;
        tau.mutable_at(k) = e.tau;
        T.middleCols(slam::BlockColumn(static_cast<int>(k), d), d) = e.R;
        T.col(slam::BlockColumn(static_cast<int>(k), d) + d) = e.t;
    }
    py::dict out;
    out["indices"] = indices;
    out["transforms"] = PosesToArray(T, d);
    out["kappa"] = kappa;
    out["tau"] = tau;
    return out;
}

slam::PoseGraph ReadG2o(const std::filesystem::path& path) {
    slam::PoseGraphReadResult read = slam::ReadG2o(path);
    if (!read.ok()) throw InputError(read.error);
    return std::move(read.graph);
}

void WriteG2o(const std::filesystem::path& path, const slam::PoseGraph& graph,
              const py::object& poses) {
    slam::PoseMatrix P;
    if (!poses.is_none()) {
        P = ArrayToPoses(poses.cast<Array>(), graph.d, "poses");
    } else if (graph.initial_guess) {
        P = *graph.initial_guess;
    } else {
        throw InputError("write_g2o: the graph has no initial guess: pass poses");
    }
    if (P.cols() != (graph.d + 1) * graph.n) {
        throw InputError("write_g2o: " + std::to_string(P.cols() / (graph.d + 1)) +
                         " poses for a graph of " + std::to_string(graph.n));
    }
    std::string error;
    if (!slam::WriteG2o(path, graph, P, &error)) throw InputError(error);
}

}  // namespace

void BindGraph(py::module_& m) {
    py::class_<slam::PoseGraph>(m, "PoseGraph",
                                "A pose graph: relative-pose edges between poses 0..n-1 of SE(d).")
        .def(py::init([](int d) {
                 CheckDimension(d);
                 slam::PoseGraph graph;
                 graph.d = d;
                 return graph;
             }),
             py::arg("d") = 3)
        .def_readonly("d", &slam::PoseGraph::d, "dimension, 2 or 3")
        .def_readonly("n", &slam::PoseGraph::n, "number of poses (largest index + 1)")
        .def_property_readonly("num_edges", [](const slam::PoseGraph& g) { return g.edges.size(); })
        .def("add_edge", &AddEdge, py::arg("i"), py::arg("j"), py::arg("T"), py::arg("kappa") = 1.0,
             py::arg("tau") = 1.0,
             "Adds the measurement T_i_j ((d+1, d+1)) with rotation weight kappa and translation "
             "weight tau (cost kappa ||R_j - R_i R_ij||^2 + tau ||t_j - t_i - R_i t_ij||^2).")
        .def_property("initial_guess", &InitialGuess, &SetInitialGuess,
                      "(n, d+1, d+1) poses from the file's VERTEX lines, or None")
        .def("edges", &Edges, "dict of arrays: indices (m, 2), transforms, kappa, tau")
        .def("__repr__", [](const slam::PoseGraph& g) {
            return "<certislam.PoseGraph d=" + std::to_string(g.d) + " n=" + std::to_string(g.n) +
                   " edges=" + std::to_string(g.edges.size()) + ">";
        });
    m.def("read_g2o", &ReadG2o, py::arg("path"),
          "Reads a g2o file (EDGE_SE2 / EDGE_SE3:QUAT, VERTEX_*); raises InputError naming "
          "file:line on a bad file.");
    m.def("write_g2o", &WriteG2o, py::arg("path"), py::arg("graph"), py::arg("poses") = py::none(),
          "Writes poses ((n, d+1, d+1); default the graph's initial guess) and the graph's edges.");
}

}  // namespace certislam::python
