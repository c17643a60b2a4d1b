// Trajectory files and errors for Python: the library calls of `certislam eval`.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl/filesystem.h>

#include <filesystem>
#include <string>

#include "bin/python/arrays.h"
#include "bin/python/bindings.h"
#include "slam/eval/trajectory_metrics.h"
#include "slam/io/trajectory_io.h"

namespace certislam::python {
namespace {

slam::TrajectoryFormat Format(const std::string& name) {
    slam::TrajectoryFormat format{};
    if (!slam::ParseTrajectoryFormat(name, &format)) {
        throw InputError("format = '" + name + "': must be 'tum' or 'kitti'");
    }
    return format;
}

py::tuple ReadTrajectory(const std::filesystem::path& path, const std::string& format) {
    const slam::TrajectoryReadResult read = slam::ReadTrajectory(path, Format(format));
    if (read.status != slam::TrajectoryReadResult::Status::kOk) throw InputError(read.error);
    return py::make_tuple(TrajectoryStamps(read.trajectory), TrajectoryPoses(read.trajectory));
}

void WriteTrajectory(const std::filesystem::path& path, const Array& poses,
                     const py::object& stamps, const std::string& format) {
    const slam::Trajectory trajectory = ToTrajectory(poses, stamps, "poses");
    std::string error;
    if (!slam::WriteTrajectory(path, trajectory, Format(format), &error)) throw InputError(error);
}

py::dict Eval(const Array& gt, const Array& est, const py::object& gt_stamps,
              const py::object& est_stamps, bool align, double max_diff_s) {
    if (gt_stamps.is_none() != est_stamps.is_none()) {
        throw InputError("eval: give stamps for both trajectories or for neither");
    }
    slam::AssociationConfig association;
    association.by_index = gt_stamps.is_none();  // no stamps: pose k pairs with pose k (KITTI)
    association.max_diff_s = max_diff_s;
    try {
        association.Validate();
    } catch (const std::invalid_argument& e) {
        throw InputError(e.what());
    }
    const slam::AssociatedPoses pairs = slam::Associate(
        ToTrajectory(gt, gt_stamps, "gt"), ToTrajectory(est, est_stamps, "est"), association);
    const slam::TeamErrors team = slam::EvaluateTeam({pairs}, align);
    if (team.status != slam::TeamErrors::Status::kOk) {
        throw InputError("eval: no pose pairs associated (max_diff_s " +
                         std::to_string(max_diff_s) + ")");
    }
    Array T(std::vector<py::ssize_t>{4, 4});
    for (int r = 0; r < 4; ++r) {
        for (int c = 0; c < 4; ++c) T.mutable_at(r, c) = team.T_gt_est.matrix()(r, c);
    }
    py::dict out;
    out["pairs"] = team.pairs;
    out["ate_rmse"] = team.ate_rmse;
    out["rpe_rmse"] = team.rpe_rmse;
    out["T_gt_est"] = T;
    return out;
}

}  // namespace

void BindEval(py::module_& m) {
    m.def("read_trajectory", &ReadTrajectory, py::arg("path"), py::arg("format") = "tum",
          "Reads a TUM or KITTI file: (stamps (N,), poses (N, 4, 4)); raises InputError naming "
          "file:line on a bad file.");
    m.def("write_trajectory", &WriteTrajectory, py::arg("path"), py::arg("poses"),
          py::arg("stamps") = py::none(), py::arg("format") = "tum",
          "Writes poses (N, 4, 4) with stamps (default 0, 1, ...) as TUM or KITTI.");
    m.def("eval", &Eval, py::arg("gt"), py::arg("est"), py::arg("gt_stamps") = py::none(),
          py::arg("est_stamps") = py::none(), py::arg("align") = true, py::arg("max_diff_s") = 0.01,
          "ATE RMSE (after Umeyama SE(3) alignment unless align=False) and RPE RMSE (delta 1) of "
          "est against gt, evo's conventions; poses (N, 4, 4), paired by stamp when stamps are "
          "given, else by index. Returns a dict: pairs, ate_rmse, rpe_rmse, T_gt_est.");
}

}  // namespace certislam::python
