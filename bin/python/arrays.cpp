// numpy <-> algorithm types (see arrays.h).
#include "bin/python/arrays.h"

#include <cmath>

namespace certislam::python {
namespace {

Array NewArray(std::initializer_list<py::ssize_t> shape) {
    return Array(std::vector<py::ssize_t>(shape));
}

void CheckShape(const Array& array, std::initializer_list<py::ssize_t> tail,
                const std::string& what) {
    const auto rank = static_cast<py::ssize_t>(tail.size()) + 1;
    bool ok = array.ndim() == rank;
    py::ssize_t axis = 1;
    for (const py::ssize_t size : tail) ok = ok && array.shape(axis++) == size;
    if (ok) return;
    std::string expected = "(N";
    for (const py::ssize_t size : tail) expected += ", " + std::to_string(size);
    std::string got = "(";
    for (py::ssize_t a = 0; a < array.ndim(); ++a) {
        got += (a ? ", " : "") + std::to_string(array.shape(a));
    }
    throw InputError(what + ": shape " + got + ") where " + expected + ") was expected");
}

}  // namespace

Array PosesToArray(const slam::PoseMatrix& poses, int d) {
    const int n = static_cast<int>(poses.cols()) / (d + 1);
    Array out = NewArray({n, d + 1, d + 1});
    auto a = out.mutable_unchecked<3>();
    for (int g = 0; g < n; ++g) {
        for (int r = 0; r <= d; ++r) {
            for (int c = 0; c <= d; ++c) {
                a(g, r, c) = r < d ? poses(r, slam::BlockColumn(g, d) + c) : (c == d ? 1.0 : 0.0);
            }
        }
    }
    return out;
}

slam::PoseMatrix ArrayToPoses(const Array& array, int d, const std::string& what) {
    CheckShape(array, {d + 1, d + 1}, what);
    const auto a = array.unchecked<3>();
    const int n = static_cast<int>(array.shape(0));
    slam::PoseMatrix poses(d, (d + 1) * n);
    for (int g = 0; g < n; ++g) {
        for (int r = 0; r < d; ++r) {
            for (int c = 0; c <= d; ++c) {
                if (!std::isfinite(a(g, r, c))) {
                    throw InputError(what + "[" + std::to_string(g) + "]: non-finite entry");
                }
                poses(r, slam::BlockColumn(g, d) + c) = a(g, r, c);
            }
        }
        const Eigen::MatrixXd R = poses.middleCols(slam::BlockColumn(g, d), d);
        const double off = (R.transpose() * R - Eigen::MatrixXd::Identity(d, d)).norm();
        if (off > kRotationTolerance || R.determinant() <= 0.0) {
            throw InputError(what + "[" + std::to_string(g) + "]: rotation block is not in SO(" +
                             std::to_string(d) + ") (||R^T R - I|| = " + std::to_string(off) +
                             ", det " + std::to_string(R.determinant()) + ")");
        }
    }
    return poses;
}

Array Rotations(const slam::PoseMatrix& poses, int d) {
    const int n = static_cast<int>(poses.cols()) / (d + 1);
    Array out = NewArray({n, d, d});
    auto a = out.mutable_unchecked<3>();
    for (int g = 0; g < n; ++g) {
        for (int r = 0; r < d; ++r) {
            for (int c = 0; c < d; ++c) a(g, r, c) = poses(r, slam::BlockColumn(g, d) + c);
        }
    }
    return out;
}

Array Translations(const slam::PoseMatrix& poses, int d) {
    const int n = static_cast<int>(poses.cols()) / (d + 1);
    Array out = NewArray({n, d});
    auto a = out.mutable_unchecked<2>();
    for (int g = 0; g < n; ++g) {
        for (int r = 0; r < d; ++r) a(g, r) = poses(r, slam::BlockColumn(g, d) + d);
    }
    return out;
}

Array TrajectoryPoses(const slam::Trajectory& trajectory) {
    const auto n = static_cast<py::ssize_t>(trajectory.size());
    Array out = NewArray({n, 4, 4});
    auto a = out.mutable_unchecked<3>();
    for (py::ssize_t k = 0; k < n; ++k) {
        const Eigen::Matrix4d T = trajectory[k].T_world_body.matrix();
        for (int r = 0; r < 4; ++r) {
            for (int c = 0; c < 4; ++c) a(k, r, c) = T(r, c);
        }
    }
    return out;
}

Array TrajectoryStamps(const slam::Trajectory& trajectory) {
    Array out = NewArray({static_cast<py::ssize_t>(trajectory.size())});
    auto a = out.mutable_unchecked<1>();
    for (size_t k = 0; k < trajectory.size(); ++k) a(k) = trajectory[k].stamp_s;
    return out;
}

slam::Trajectory ToTrajectory(const Array& poses, const py::object& stamps,
                              const std::string& what) {
    const slam::PoseMatrix P = ArrayToPoses(poses, 3, what);
    const int n = static_cast<int>(poses.shape(0));
    Array t = stamps.is_none() ? Array() : stamps.cast<Array>();
    if (!stamps.is_none() && (t.ndim() != 1 || t.shape(0) != n)) {
        throw InputError(what + ": " + std::to_string(n) + " poses need " + std::to_string(n) +
                         " stamps");
    }
    slam::Trajectory trajectory(n);
    for (int k = 0; k < n; ++k) {
        trajectory[k].stamp_s = stamps.is_none() ? k : t.at(k);
        trajectory[k].T_world_body.linear() = P.middleCols(slam::BlockColumn(k, 3), 3);
        trajectory[k].T_world_body.translation() = P.col(slam::BlockColumn(k, 3) + 3);
    }
    return trajectory;
}

}  // namespace certislam::python
