#pragma once

// The coefficients of an angle-axis rotation w (theta = |w|, radians) shared by the BAL camera's
// analytic Jacobians: R = I + a W + b W^2 and the right Jacobian J_r = I - b W + c W^2 of SO(3)
// with W = [w]x, a = sin(theta)/theta, b = (1 - cos(theta))/theta^2,
// c = (theta - sin(theta))/theta^3 (Taylor series below 1e-3 rad, as lie::angle_axis_rotate()).

#include <Eigen/Core>
#include <cmath>

namespace carat::internal {

/// R(w), J_r(w) and W = [w]x of an angle-axis rotation.
struct AngleAxisTerms {
  Eigen::Matrix3d W;    ///< [w]x
  Eigen::Matrix3d R;    ///< the rotation
  Eigen::Matrix3d J_r;  ///< the right Jacobian: d (R(w) X) / d w = -R [X]x J_r
};

/// [v]x, the cross-product matrix.
inline Eigen::Matrix3d cross_matrix(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return m;
}

/// The terms of the rotation w (radians).
[[gnu::always_inline]] inline AngleAxisTerms angle_axis_terms(const Eigen::Vector3d& w) {
  const double theta2 = w.squaredNorm();
  double a, b, c;
  if (theta2 > 1e-6) {
    const double theta = std::sqrt(theta2);
    const double s = std::sin(theta);
    a = s / theta;
    b = (1.0 - std::cos(theta)) / theta2;
    c = (theta - s) / (theta2 * theta);
  } else {
    a = 1.0 - theta2 / 6.0;
    b = 0.5 - theta2 / 24.0;
    c = 1.0 / 6.0 - theta2 / 120.0;
  }
  AngleAxisTerms out;
  out.W = cross_matrix(w);
  const Eigen::Matrix3d W2 = out.W * out.W;
  out.R = Eigen::Matrix3d::Identity() + a * out.W + b * W2;
  out.J_r = Eigen::Matrix3d::Identity() - b * out.W + c * W2;
  return out;
}

}  // namespace carat::internal
