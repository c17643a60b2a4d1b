// The parts of the `certislam` Python module, each adding its functions and classes to it.
#pragma once

#include <pybind11/pybind11.h>

namespace certislam::python {

/// PoseGraph (in memory, from numpy), read_g2o, write_g2o.
void BindGraph(pybind11::module_& m);

/// solve (file or PoseGraph -> certified poses) and certify (graph + poses -> verdict, bound).
void BindSolve(pybind11::module_& m);

/// read_trajectory, write_trajectory, eval (ATE / RPE, evo's conventions).
void BindEval(pybind11::module_& m);

}  // namespace certislam::python
