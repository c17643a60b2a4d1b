// numpy <-> algorithm types for the Python module: poses as (N, d+1, d+1) homogeneous arrays.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <Eigen/Core>
#include <stdexcept>
#include <string>

#include "slam/core/pose_graph.h"
#include "slam/core/trajectory.h"

namespace certislam::python {

namespace py = pybind11;

/// A float64 C-contiguous array (numpy converts other dtypes and layouts on the way in).
using Array = py::array_t<double, py::array::c_style | py::array::forcecast>;

/// Bad input from Python (a file that does not parse, an array of the wrong shape): raised as
/// certislam.InputError, a ValueError, with the file:line or argument named in the message.
struct InputError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

/// Largest ||R^T R - I||_F accepted for a rotation given from Python (a rotation that far off
/// is not a rounding of one).
inline constexpr double kRotationTolerance = 1e-3;

/// Poses (d x (d+1)n, blocks [R_g t_g]) as an (n, d+1, d+1) array of homogeneous transforms.
Array PosesToArray(const slam::PoseMatrix& poses, int d);

/// The inverse of PosesToArray; `what` names the argument in errors (shape, non-finite
/// entries, rotations off SO(d) beyond kRotationTolerance).
slam::PoseMatrix ArrayToPoses(const Array& array, int d, const std::string& what);

/// Rotation blocks of `poses` as an (n, d, d) array.
Array Rotations(const slam::PoseMatrix& poses, int d);

/// Translations of `poses` as an (n, d) array.
Array Translations(const slam::PoseMatrix& poses, int d);

/// A trajectory's poses as (N, 4, 4) and its stamps as (N,).
Array TrajectoryPoses(const slam::Trajectory& trajectory);
Array TrajectoryStamps(const slam::Trajectory& trajectory);

/// A trajectory from (N, 4, 4) poses and (N,) stamps (stamps None: 0, 1, 2, ...).
slam::Trajectory ToTrajectory(const Array& poses, const py::object& stamps,
                              const std::string& what);

}  // namespace certislam::python
