// The `certislam` Python module: thin glue over slam/ and certify/ (poses as numpy arrays).
#include <pybind11/pybind11.h>

#include "bin/python/arrays.h"
#include "bin/python/bindings.h"

PYBIND11_MODULE(certislam, m) {
    namespace py = pybind11;
    m.doc() =
        "certislam: certifiably optimal pose-graph optimisation (RBCD + dual certificate), g2o "
        "I/O and trajectory errors. Poses are (N, d+1, d+1) numpy arrays of T_world_pose.";
    m.attr("__version__") = CERTISLAM_VERSION;
    py::register_exception<certislam::python::InputError>(m, "InputError", PyExc_ValueError);
    certislam::python::BindGraph(m);
    certislam::python::BindSolve(m);
    certislam::python::BindEval(m);
}
