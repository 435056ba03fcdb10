#pragma once

/// SE(3) Lie-group helpers. Tangent vectors are xi = [omega, v] (rotation first, radians then
/// metres), as in gtsam_points and small_gicp. The storage of an SE(3) variable is 7 doubles
/// [qx, qy, qz, qw, tx, ty, tz] (Eigen's quaternion coefficient order, then the translation).

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace carat::se3 {

/// 6-vector of an SE(3) tangent: [omega (rad), v (m)].
using Vector6d = Eigen::Matrix<double, 6, 1>;
/// 6x6 matrix on SE(3) tangents.
using Matrix6d = Eigen::Matrix<double, 6, 6>;

/// Exp: tangent [omega, v] -> rigid transform (full SE(3) exponential, not a product retraction).
Eigen::Isometry3d exp(const Vector6d& xi);

/// Log: rigid transform -> tangent [omega, v] (inverse of exp).
Vector6d log(const Eigen::Isometry3d& T);

/// Adjoint Ad(T) mapping right-tangents to left-tangents: T Exp(xi) = Exp(Ad(T) xi) T.
Matrix6d adjoint(const Eigen::Isometry3d& T);

/// Reads the 7-double storage [qx, qy, qz, qw, tx, ty, tz] (the quaternion is normalized).
Eigen::Isometry3d from_storage(const double* storage);

/// Writes a rigid transform into the 7-double storage [qx, qy, qz, qw, tx, ty, tz].
void to_storage(const Eigen::Isometry3d& T, double* storage);

/// Builds a rigid transform from a quaternion (normalized here) and a translation.
Eigen::Isometry3d make(const Eigen::Quaterniond& q, const Eigen::Vector3d& t);

/// What keeps T from being a rigid transform, or nullptr: not finite, a rotation block that is
/// not orthonormal (|R^T R - I| > 1e-6, Frobenius: scaled or sheared) or a reflection (det < 0).
const char* rigid_transform_problem(const Eigen::Isometry3d& T);

}  // namespace carat::se3
