#pragma once

/// SE(2) Lie-group helpers. Tangent vectors are xi = [omega, vx, vy] (rotation first, radians
/// then metres), the order of carat's SE(3) tangents. The storage of an SE(2) variable is 3
/// doubles [x, y, theta] (metres, metres, radians) with theta wrapped to (-pi, pi].

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace carat::se2 {

/// 3x3 matrix on SE(2) tangents [omega, vx, vy].
using Matrix3d = Eigen::Matrix3d;

/// The angle `theta` (radians) wrapped to (-pi, pi].
double wrap_angle(double theta);

/// The heading (radians, in (-pi, pi]) of a planar rigid transform.
double angle(const Eigen::Isometry2d& T);

/// Exp: tangent [omega (rad), vx (m), vy (m)] -> planar rigid transform (full SE(2) exponential).
Eigen::Isometry2d exp(const Eigen::Vector3d& xi);

/// Log: planar rigid transform -> tangent [omega, vx, vy] with omega in (-pi, pi] (inverse of
/// exp).
Eigen::Vector3d log(const Eigen::Isometry2d& T);

/// Adjoint Ad(T) mapping right-tangents to left-tangents: T Exp(xi) = Exp(Ad(T) xi) T.
Matrix3d adjoint(const Eigen::Isometry2d& T);

/// Right Jacobian J_r(xi): Exp(xi + d) ~= Exp(xi) Exp(J_r(xi) d), for |omega| < 2 pi.
Matrix3d right_jacobian(const Eigen::Vector3d& xi);

/// Inverse of the right Jacobian: Log(Exp(xi) Exp(d)) ~= xi + J_r^-1(xi) d, for |omega| < 2 pi.
Matrix3d right_jacobian_inverse(const Eigen::Vector3d& xi);

/// Reads the 3-double storage [x, y, theta] (metres, radians).
Eigen::Isometry2d from_storage(const double* storage);

/// Writes a planar rigid transform into the 3-double storage [x, y, theta], theta in (-pi, pi].
void to_storage(const Eigen::Isometry2d& T, double* storage);

/// Builds a planar rigid transform from a position (metres) and a heading theta (radians).
Eigen::Isometry2d make(double x, double y, double theta);

/// What keeps T from being a rigid transform, or nullptr: not finite, a rotation block that is
/// not orthonormal (|R^T R - I| > 1e-6, Frobenius: scaled or sheared) or a reflection (det < 0).
const char* rigid_transform_problem(const Eigen::Isometry2d& T);

}  // namespace carat::se2
