#pragma once

// Internal: the one test of a rigid transform that SE(2) and SE(3) share (se2.cpp, se3.cpp).

#include <Eigen/Geometry>

namespace carat::internal {

/// What keeps T from being a rigid transform, or nullptr (see se3::rigid_transform_problem()).
template <int D>
const char* rigid_problem(const Eigen::Transform<double, D, Eigen::Isometry>& T) {
  if (!T.matrix().allFinite()) return "is not finite";
  const Eigen::Matrix<double, D, D> R = T.linear();
  const double error = (R.transpose() * R - Eigen::Matrix<double, D, D>::Identity()).norm();
  if (!(error <= 1e-6)) {
    return "has a rotation block that is not orthonormal (scaled or sheared: |R^T R - I| > 1e-6)";
  }
  if (!(R.determinant() > 0.0)) return "has a reflection, not a rotation (det R < 0)";
  return nullptr;
}

}  // namespace carat::internal
