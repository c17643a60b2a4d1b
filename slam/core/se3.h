// Small SE(3) helpers shared by the front end's covariance code (PCM, registration quality).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace certislam::slam {

using Matrix6 = Eigen::Matrix<double, 6, 6>;  ///< covariance/information of a twist (v, w)
using Vector6 = Eigen::Matrix<double, 6, 1>;  ///< twist ordered (translation, rotation)

/// Skew-symmetric matrix of v: Hat(v) * u = v x u.
inline Eigen::Matrix3d Hat(const Eigen::Vector3d& v) {
    Eigen::Matrix3d m;
    m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
    return m;
}

/// Adjoint of T for twists ordered (v, w): T exp(d) = exp(Ad_T d) T.
inline Matrix6 Adjoint(const Eigen::Isometry3d& T) {
    Matrix6 ad = Matrix6::Zero();
    const Eigen::Matrix3d R = T.rotation();
    ad.topLeftCorner<3, 3>() = R;
    ad.topRightCorner<3, 3>() = Hat(T.translation()) * R;
    ad.bottomRightCorner<3, 3>() = R;
    return ad;
}

}  // namespace certislam::slam
