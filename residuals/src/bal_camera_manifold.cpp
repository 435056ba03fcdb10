#include "carat/residuals/bal_camera_manifold.hpp"

#include <Eigen/Core>
#include <cmath>

#include "angle_axis_terms.hpp"
#include "carat/solver/lie_functions.hpp"

namespace carat {
namespace {

/// The camera centre c = -R(w)^T t of `camera` (world frame, scene units).
Eigen::Vector3d centre_of(const double* camera) {
  const double minus_w[3] = {-camera[0], -camera[1], -camera[2]};
  Eigen::Vector3d c;
  lie::angle_axis_rotate(minus_w, camera + 3, c.data());  // R(w)^T t
  return -c;
}

}  // namespace

void BalCameraManifold::plus(const double* x, const double* delta, double* x_plus_delta) const {
  const Eigen::Vector3d c = centre_of(x) + Eigen::Map<const Eigen::Vector3d>(delta + 3);
  double w[3] = {x[0] + delta[0], x[1] + delta[1], x[2] + delta[2]};
  double t[3];
  lie::angle_axis_rotate(w, c.data(), t);
  for (int k = 0; k < 3; ++k) {
    x_plus_delta[k] = w[k];
    x_plus_delta[3 + k] = -t[k];
  }
  for (int k = 6; k < 9; ++k) x_plus_delta[k] = x[k] + delta[k];
}

void BalCameraManifold::minus(const double* y, const double* x, double* delta) const {
  const Eigen::Vector3d dc = centre_of(y) - centre_of(x);
  for (int k = 0; k < 3; ++k) {
    delta[k] = y[k] - x[k];
    delta[3 + k] = dc[k];
  }
  for (int k = 6; k < 9; ++k) delta[k] = y[k] - x[k];
}

void BalCameraManifold::plus_jacobian(const double* x, double* jacobian) const {
  // t' = -R(w + dw) (c + dc): d t' / d dw = R [c]x J_r(w) (as d (R X) / d w = -R [X]x J_r),
  // d t' / d dc = -R.
  const internal::AngleAxisTerms terms =
      internal::angle_axis_terms(Eigen::Map<const Eigen::Vector3d>(x));
  Eigen::Map<Eigen::Matrix<double, 9, 9, Eigen::RowMajor>> J(jacobian);
  J.setIdentity();
  J.block<3, 3>(3, 0) = terms.R * internal::cross_matrix(centre_of(x)) * terms.J_r;
  J.block<3, 3>(3, 3) = -terms.R;
}

bool BalCameraManifold::is_valid(const double* x) const {
  for (int k = 0; k < 9; ++k) {
    if (!std::isfinite(x[k])) return false;
  }
  return true;
}

std::shared_ptr<const Manifold> bal_camera_manifold() {
  static const auto manifold = std::make_shared<const BalCameraManifold>();
  return manifold;
}

}  // namespace carat
