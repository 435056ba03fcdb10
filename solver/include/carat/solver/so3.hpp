#pragma once

/// SO(3) Lie-group helpers. Rotation vectors are in radians; Exp/Log are the matrix exponential
/// and its principal logarithm (angle in [0, pi]).

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace carat::so3 {

/// The skew-symmetric matrix [w]x with [w]x v = w x v.
Eigen::Matrix3d hat(const Eigen::Vector3d& w);

/// The rotation vector of a skew-symmetric matrix (inverse of hat).
Eigen::Vector3d vee(const Eigen::Matrix3d& W);

/// Exp: rotation vector (radians) -> rotation quaternion (unit).
Eigen::Quaterniond exp(const Eigen::Vector3d& omega);

/// Log: unit quaternion -> rotation vector (radians), angle in [0, pi].
Eigen::Vector3d log(const Eigen::Quaterniond& q);

/// Left Jacobian J_l(w) of SO(3): Exp(w + dw) ~= Exp(J_l(w) dw) Exp(w).
Eigen::Matrix3d left_jacobian(const Eigen::Vector3d& omega);

/// Right Jacobian J_r(w) = J_l(-w): Exp(w + dw) ~= Exp(w) Exp(J_r(w) dw).
Eigen::Matrix3d right_jacobian(const Eigen::Vector3d& omega);

/// Inverse of the right Jacobian: Log(Exp(w) Exp(d)) ~= w + J_r^-1(w) d.
Eigen::Matrix3d right_jacobian_inverse(const Eigen::Vector3d& omega);

}  // namespace carat::so3
