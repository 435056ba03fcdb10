#include "carat/solver/manifold.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "carat/base/error.hpp"
#include "carat/solver/se2.hpp"
#include "carat/solver/se3.hpp"
#include "carat/solver/so3.hpp"

namespace carat {
namespace {

bool all_finite(const double* x, int n) {
  for (int i = 0; i < n; ++i) {
    if (!std::isfinite(x[i])) return false;
  }
  return true;
}

bool unit_quaternion(const double* q) {
  const double n2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
  return std::abs(n2 - 1.0) < 1e-6;
}

Eigen::Quaterniond read_quaternion(const double* x) { return {x[3], x[0], x[1], x[2]}; }

void write_quaternion(Eigen::Quaterniond q, double* out) {
  q.normalize();
  out[0] = q.x();
  out[1] = q.y();
  out[2] = q.z();
  out[3] = q.w();
}

/// d(q Exp(w)) / dw at w = 0 for q = [qx, qy, qz, qw]: 1/2 q * [e_j, 0], as 4 rows of a
/// row-major matrix with `stride` columns starting at `out`.
void quaternion_plus_jacobian(const double* q, double* out, int stride) {
  const double x = q[0], y = q[1], z = q[2], w = q[3];
  const double rows[4][3] = {{w, -z, y}, {z, w, -x}, {-y, x, w}, {-x, -y, -z}};
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 3; ++c) out[r * stride + c] = 0.5 * rows[r][c];
  }
}

}  // namespace

void Manifold::plus_jacobian(const double* x, double* jacobian) const {
  const int a = ambient_size();
  const int t = tangent_size();
  constexpr double kStep = 1e-6;
  std::vector<double> delta(static_cast<std::size_t>(t), 0.0);
  std::vector<double> forward(static_cast<std::size_t>(a)), backward(static_cast<std::size_t>(a));
  for (int j = 0; j < t; ++j) {
    delta[static_cast<std::size_t>(j)] = kStep;
    plus(x, delta.data(), forward.data());
    delta[static_cast<std::size_t>(j)] = -kStep;
    plus(x, delta.data(), backward.data());
    delta[static_cast<std::size_t>(j)] = 0.0;
    for (int i = 0; i < a; ++i) {
      jacobian[i * t + j] =
          (forward[static_cast<std::size_t>(i)] - backward[static_cast<std::size_t>(i)]) /
          (2.0 * kStep);
    }
  }
}

EuclideanManifold::EuclideanManifold(int size) : size_(size) {
  if (size < 1) throw Error("EuclideanManifold: size must be >= 1, got " + std::to_string(size));
}

void EuclideanManifold::plus(const double* x, const double* delta, double* out) const {
  for (int i = 0; i < size_; ++i) out[i] = x[i] + delta[i];
}

void EuclideanManifold::minus(const double* y, const double* x, double* delta) const {
  for (int i = 0; i < size_; ++i) delta[i] = y[i] - x[i];
}

void EuclideanManifold::plus_jacobian(const double* /*x*/, double* jacobian) const {
  for (int i = 0; i < size_; ++i) {
    for (int j = 0; j < size_; ++j) jacobian[i * size_ + j] = i == j ? 1.0 : 0.0;
  }
}

bool EuclideanManifold::is_valid(const double* x) const { return all_finite(x, size_); }

void SO3Manifold::plus(const double* x, const double* delta, double* out) const {
  const Eigen::Quaterniond q =
      read_quaternion(x) * so3::exp(Eigen::Map<const Eigen::Vector3d>(delta));
  write_quaternion(q, out);
}

void SO3Manifold::minus(const double* y, const double* x, double* delta) const {
  const Eigen::Vector3d w = so3::log(read_quaternion(x).conjugate() * read_quaternion(y));
  Eigen::Map<Eigen::Vector3d> out(delta);
  out = w;
}

void SO3Manifold::plus_jacobian(const double* x, double* jacobian) const {
  quaternion_plus_jacobian(x, jacobian, 3);
}

bool SO3Manifold::is_valid(const double* x) const { return all_finite(x, 4) && unit_quaternion(x); }

void SE3Manifold::plus(const double* x, const double* delta, double* out) const {
  const Eigen::Isometry3d T =
      se3::from_storage(x) * se3::exp(Eigen::Map<const se3::Vector6d>(delta));
  se3::to_storage(T, out);
}

void SE3Manifold::minus(const double* y, const double* x, double* delta) const {
  const se3::Vector6d xi = se3::log(se3::from_storage(x).inverse() * se3::from_storage(y));
  Eigen::Map<se3::Vector6d> out(delta);
  out = xi;
}

void SE3Manifold::plus_jacobian(const double* x, double* jacobian) const {
  // [q; t] [+] [w; v] = [q Exp(w); t + R(q) V(w) v]: at 0, dq/dw as for SO(3), dt/dv = R.
  std::fill(jacobian, jacobian + 42, 0.0);
  quaternion_plus_jacobian(x, jacobian, 6);
  const Eigen::Matrix3d R = read_quaternion(x).normalized().toRotationMatrix();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) jacobian[(4 + r) * 6 + 3 + c] = R(r, c);
  }
}

bool SE3Manifold::is_valid(const double* x) const { return all_finite(x, 7) && unit_quaternion(x); }

void SE2Manifold::plus(const double* x, const double* delta, double* out) const {
  // [t; theta] [+] [w; v] = [t + R(theta) V(w) v; theta + w]: the heading is summed directly so
  // that it does not pass through a rotation matrix.
  const Eigen::Vector2d step = se2::exp(Eigen::Map<const Eigen::Vector3d>(delta)).translation();
  const double c = std::cos(x[2]), s = std::sin(x[2]);
  const double theta = se2::wrap_angle(x[2] + delta[0]);
  out[0] = x[0] + c * step.x() - s * step.y();
  out[1] = x[1] + s * step.x() + c * step.y();
  out[2] = theta;
}

void SE2Manifold::minus(const double* y, const double* x, double* delta) const {
  const Eigen::Vector3d xi = se2::log(se2::from_storage(x).inverse() * se2::from_storage(y));
  Eigen::Map<Eigen::Vector3d> out(delta);
  out = xi;
}

void SE2Manifold::plus_jacobian(const double* x, double* jacobian) const {
  // At 0: d theta / d w = 1, d t / d v = R(theta).
  const double c = std::cos(x[2]), s = std::sin(x[2]);
  const double rows[3][3] = {{0.0, c, -s}, {0.0, s, c}, {1.0, 0.0, 0.0}};
  for (int r = 0; r < 3; ++r) {
    for (int k = 0; k < 3; ++k) jacobian[r * 3 + k] = rows[r][k];
  }
}

bool SE2Manifold::is_valid(const double* x) const {
  return all_finite(x, 3) && x[2] > -std::numbers::pi && x[2] <= std::numbers::pi;
}

std::shared_ptr<const Manifold> se2_manifold() {
  static const auto instance = std::make_shared<const SE2Manifold>();
  return instance;
}

std::shared_ptr<const Manifold> se3_manifold() {
  static const auto instance = std::make_shared<const SE3Manifold>();
  return instance;
}

std::shared_ptr<const Manifold> so3_manifold() {
  static const auto instance = std::make_shared<const SO3Manifold>();
  return instance;
}

std::shared_ptr<const Manifold> euclidean_manifold(int size) {
  return std::make_shared<const EuclideanManifold>(size);
}

}  // namespace carat
