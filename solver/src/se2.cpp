#include "carat/solver/se2.hpp"

#include <cmath>
#include <numbers>

#include "rigid_check.hpp"

namespace carat::se2 {
namespace {

/// sin(w) / w, (1 - cos(w)) / w, (1 - cos(w)) / w^2 and (w - sin(w)) / w^2, with Taylor
/// series near w = 0.
struct AngleTerms {
  double a, b, c, d;
};

AngleTerms angle_terms(double w) {
  const double w2 = w * w;
  if (std::abs(w) < 1e-4) {
    return {1.0 - w2 / 6.0, w / 2.0 - w * w2 / 24.0, 0.5 - w2 / 24.0, w / 6.0 - w * w2 / 120.0};
  }
  const double s = std::sin(w), c = std::cos(w);
  return {s / w, (1.0 - c) / w, (1.0 - c) / w2, (w - s) / w2};
}

}  // namespace

double wrap_angle(double theta) {
  constexpr double kPi = std::numbers::pi;
  double wrapped = std::remainder(theta, 2.0 * kPi);
  if (wrapped <= -kPi) wrapped += 2.0 * kPi;
  return wrapped;
}

double angle(const Eigen::Isometry2d& T) {
  return wrap_angle(std::atan2(T.linear()(1, 0), T.linear()(0, 0)));
}

Eigen::Isometry2d exp(const Eigen::Vector3d& xi) {
  const AngleTerms t = angle_terms(xi[0]);
  // V(w) = a I + b [0 -1; 1 0].
  Eigen::Isometry2d T = Eigen::Isometry2d::Identity();
  T.linear() = Eigen::Rotation2Dd(xi[0]).toRotationMatrix();
  T.translation() = Eigen::Vector2d(t.a * xi[1] - t.b * xi[2], t.b * xi[1] + t.a * xi[2]);
  return T;
}

Eigen::Vector3d log(const Eigen::Isometry2d& T) {
  const double w = angle(T);
  const AngleTerms t = angle_terms(w);
  // V^-1 = (a I - b [0 -1; 1 0]) / (a^2 + b^2).
  const double n = t.a * t.a + t.b * t.b;
  const Eigen::Vector2d& p = T.translation();
  return {w, (t.a * p.x() + t.b * p.y()) / n, (-t.b * p.x() + t.a * p.y()) / n};
}

Matrix3d adjoint(const Eigen::Isometry2d& T) {
  Matrix3d Ad = Matrix3d::Zero();
  Ad(0, 0) = 1.0;
  Ad(1, 0) = T.translation().y();
  Ad(2, 0) = -T.translation().x();
  Ad.bottomRightCorner<2, 2>() = T.linear();
  return Ad;
}

Matrix3d right_jacobian(const Eigen::Vector3d& xi) {
  const AngleTerms t = angle_terms(xi[0]);
  Matrix3d J = Matrix3d::Zero();
  J(0, 0) = 1.0;
  J(1, 0) = xi[1] * t.d - xi[2] * t.c;
  J(2, 0) = xi[1] * t.c + xi[2] * t.d;
  J(1, 1) = t.a;
  J(1, 2) = t.b;
  J(2, 1) = -t.b;
  J(2, 2) = t.a;
  return J;
}

Matrix3d right_jacobian_inverse(const Eigen::Vector3d& xi) {
  // J_r = [1 0; c A] with A = a I - b [0 -1; 1 0], so J_r^-1 = [1 0; -A^-1 c A^-1].
  const Matrix3d J = right_jacobian(xi);
  const Eigen::Matrix2d A_inverse = J.bottomRightCorner<2, 2>().inverse();
  Matrix3d J_inverse = Matrix3d::Zero();
  J_inverse(0, 0) = 1.0;
  J_inverse.bottomRightCorner<2, 2>() = A_inverse;
  J_inverse.bottomLeftCorner<2, 1>() = -A_inverse * J.bottomLeftCorner<2, 1>();
  return J_inverse;
}

Eigen::Isometry2d from_storage(const double* storage) {
  return make(storage[0], storage[1], storage[2]);
}

void to_storage(const Eigen::Isometry2d& T, double* storage) {
  storage[0] = T.translation().x();
  storage[1] = T.translation().y();
  storage[2] = angle(T);
}

Eigen::Isometry2d make(double x, double y, double theta) {
  Eigen::Isometry2d T = Eigen::Isometry2d::Identity();
  T.linear() = Eigen::Rotation2Dd(theta).toRotationMatrix();
  T.translation() = Eigen::Vector2d(x, y);
  return T;
}

const char* rigid_transform_problem(const Eigen::Isometry2d& T) {
  return internal::rigid_problem(T);
}

}  // namespace carat::se2
