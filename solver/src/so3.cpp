#include "carat/solver/so3.hpp"

#include <cmath>

namespace carat::so3 {
namespace {
constexpr double kSmallAngle = 1e-8;
}

Eigen::Matrix3d hat(const Eigen::Vector3d& w) {
  Eigen::Matrix3d W;
  W << 0.0, -w.z(), w.y(), w.z(), 0.0, -w.x(), -w.y(), w.x(), 0.0;
  return W;
}

Eigen::Vector3d vee(const Eigen::Matrix3d& W) { return {W(2, 1), W(0, 2), W(1, 0)}; }

Eigen::Quaterniond exp(const Eigen::Vector3d& omega) {
  const double theta2 = omega.squaredNorm();
  const double theta = std::sqrt(theta2);
  double real = 0.0;
  double imag_factor = 0.0;
  if (theta < kSmallAngle) {
    // Taylor: cos(t/2) = 1 - t^2/8, sin(t/2)/t = 1/2 - t^2/48.
    real = 1.0 - theta2 / 8.0;
    imag_factor = 0.5 - theta2 / 48.0;
  } else {
    real = std::cos(0.5 * theta);
    imag_factor = std::sin(0.5 * theta) / theta;
  }
  Eigen::Quaterniond q(real, imag_factor * omega.x(), imag_factor * omega.y(),
                       imag_factor * omega.z());
  q.normalize();
  return q;
}

Eigen::Vector3d log(const Eigen::Quaterniond& q_in) {
  Eigen::Quaterniond q = q_in.normalized();
  if (q.w() < 0.0) q.coeffs() = -q.coeffs();  // the same rotation, angle in [0, pi]
  const Eigen::Vector3d v = q.vec();
  const double n = v.norm();
  const double w = q.w();
  if (n < kSmallAngle) {
    // theta = 2 atan(n / w) ~= 2 n / w (1 - n^2 / (3 w^2)).
    return (2.0 / w) * (1.0 - n * n / (3.0 * w * w)) * v;
  }
  const double theta = 2.0 * std::atan2(n, w);
  return (theta / n) * v;
}

Eigen::Matrix3d left_jacobian(const Eigen::Vector3d& omega) {
  const double theta2 = omega.squaredNorm();
  const Eigen::Matrix3d W = hat(omega);
  const Eigen::Matrix3d W2 = W * W;
  if (theta2 < 1e-10) {
    return Eigen::Matrix3d::Identity() + 0.5 * W + W2 / 6.0;
  }
  const double theta = std::sqrt(theta2);
  return Eigen::Matrix3d::Identity() + ((1.0 - std::cos(theta)) / theta2) * W +
         ((theta - std::sin(theta)) / (theta2 * theta)) * W2;
}

Eigen::Matrix3d right_jacobian(const Eigen::Vector3d& omega) { return left_jacobian(-omega); }

Eigen::Matrix3d right_jacobian_inverse(const Eigen::Vector3d& omega) {
  const double theta2 = omega.squaredNorm();
  const Eigen::Matrix3d W = hat(omega);
  const Eigen::Matrix3d W2 = W * W;
  if (theta2 < 1e-10) {
    return Eigen::Matrix3d::Identity() + 0.5 * W + W2 / 12.0;
  }
  const double theta = std::sqrt(theta2);
  const double coeff = 1.0 / theta2 - (1.0 + std::cos(theta)) / (2.0 * theta * std::sin(theta));
  return Eigen::Matrix3d::Identity() + 0.5 * W + coeff * W2;
}

}  // namespace carat::so3
