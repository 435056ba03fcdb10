#pragma once

/// Rotations and rigid transforms templated on the scalar, for residual functors that carat
/// differentiates automatically (AutoDiffBlock, RelativePoseAutoDiffBlock): they work on double
/// and on Eigen's AutoDiffScalar alike. Quaternions are [qx, qy, qz, qw] (carat's storage order);
/// tangents are right perturbations, [omega, v] for SE(3) (rotation first). Near zero angles the
/// exponential and logarithm switch to Taylor series, so their derivatives stay exact there.

#include <Eigen/Core>
#include <cmath>

namespace carat::lie {

/// The value part of a scalar: the scalar itself for double, .value() of Eigen's AutoDiffScalar,
/// .a of a Ceres Jet (so that functors can branch on values, e.g. a point behind a camera).
template <typename T>
double value_of(const T& x) {
  if constexpr (requires { x.value(); }) {
    return static_cast<double>(x.value());
  } else if constexpr (requires { x.a; }) {
    return static_cast<double>(x.a);
  } else {
    return static_cast<double>(x);
  }
}

/// out = a x b.
template <typename T>
void cross(const T a[3], const T b[3], T out[3]) {
  const T x = a[1] * b[2] - a[2] * b[1];
  const T y = a[2] * b[0] - a[0] * b[2];
  const T z = a[0] * b[1] - a[1] * b[0];
  out[0] = x;
  out[1] = y;
  out[2] = z;
}

/// out = R(q) p for a unit quaternion q = [qx, qy, qz, qw] (out may alias p).
template <typename T>
void quaternion_rotate(const T q[4], const T p[3], T out[3]) {
  // p' = p + 2 w (v x p) + 2 v x (v x p), v = [qx, qy, qz].
  T vxp[3], vxvxp[3];
  cross(q, p, vxp);
  cross(q, vxp, vxvxp);
  const T two(2.0);
  const T x = p[0] + two * (q[3] * vxp[0] + vxvxp[0]);
  const T y = p[1] + two * (q[3] * vxp[1] + vxvxp[1]);
  const T z = p[2] + two * (q[3] * vxp[2] + vxvxp[2]);
  out[0] = x;
  out[1] = y;
  out[2] = z;
}

/// out = a * b (Hamilton product, [qx, qy, qz, qw] order; out may alias a or b).
template <typename T>
void quaternion_product(const T a[4], const T b[4], T out[4]) {
  const T x = a[3] * b[0] + a[0] * b[3] + a[1] * b[2] - a[2] * b[1];
  const T y = a[3] * b[1] - a[0] * b[2] + a[1] * b[3] + a[2] * b[0];
  const T z = a[3] * b[2] + a[0] * b[1] - a[1] * b[0] + a[2] * b[3];
  const T w = a[3] * b[3] - a[0] * b[0] - a[1] * b[1] - a[2] * b[2];
  out[0] = x;
  out[1] = y;
  out[2] = z;
  out[3] = w;
}

/// The unit quaternion of the rotation vector w (angle |w| in radians about w / |w|).
template <typename T>
void so3_exp(const T w[3], T q[4]) {
  using std::cos;
  using std::sin;
  using std::sqrt;
  const T theta_sq = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
  if (value_of(theta_sq) > 1e-16) {
    const T theta = sqrt(theta_sq);
    const T half = T(0.5) * theta;
    const T k = sin(half) / theta;
    q[0] = k * w[0];
    q[1] = k * w[1];
    q[2] = k * w[2];
    q[3] = cos(half);
  } else {  // sin(t/2)/t = 1/2 - t^2/48, cos(t/2) = 1 - t^2/8
    const T k = T(0.5) - theta_sq / T(48.0);
    q[0] = k * w[0];
    q[1] = k * w[1];
    q[2] = k * w[2];
    q[3] = T(1.0) - theta_sq / T(8.0);
  }
}

/// The rotation vector of a unit quaternion (angle in [0, pi]).
template <typename T>
void so3_log(const T q[4], T w[3]) {
  using std::atan2;
  using std::sqrt;
  const T s_sq = q[0] * q[0] + q[1] * q[1] + q[2] * q[2];
  // q and -q are one rotation: use the one with w >= 0 so that the angle is at most pi.
  const T sign = value_of(q[3]) < 0.0 ? T(-1.0) : T(1.0);
  T k;
  if (value_of(s_sq) > 1e-16) {
    const T s = sqrt(s_sq);
    k = T(2.0) * atan2(s, sign * q[3]) / s;
  } else {  // 2 atan(s / w) / s = 2 / w - 2 s^2 / (3 w^3)
    const T cw = sign * q[3];
    k = T(2.0) / cw - T(2.0) * s_sq / (T(3.0) * cw * cw * cw);
  }
  w[0] = sign * k * q[0];
  w[1] = sign * k * q[1];
  w[2] = sign * k * q[2];
}

/// Rodrigues' coefficients of the rotation vector w (radians): a = sin(theta) / theta and
/// b = (1 - cos(theta)) / theta^2 for theta = |w|, from their Taylor series below theta = 1e-3 rad,
/// where the closed forms lose precision.
template <typename T>
void angle_axis_coefficients(const T w[3], T* a, T* b) {
  using std::cos;
  using std::sin;
  using std::sqrt;
  const T theta_sq = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
  if (value_of(theta_sq) > 1e-6) {
    const T theta = sqrt(theta_sq);
    *a = sin(theta) / theta;
    *b = (T(1.0) - cos(theta)) / theta_sq;
  } else {
    *a = T(1.0) - theta_sq / T(6.0);
    *b = T(0.5) - theta_sq / T(24.0);
  }
}

/// out = p + a w x p + b w x (w x p) for w's coefficients a and b (angle_axis_coefficients()):
/// angle_axis_rotate() with the coefficients computed once for many points (out may alias p).
template <typename T>
void angle_axis_rotate(const T w[3], const T& a, const T& b, const T p[3], T out[3]) {
  T wxp[3], wxwxp[3];
  cross(w, p, wxp);
  cross(w, wxp, wxwxp);
  const T x = p[0] + a * wxp[0] + b * wxwxp[0];
  const T y = p[1] + a * wxp[1] + b * wxwxp[1];
  const T z = p[2] + a * wxp[2] + b * wxwxp[2];
  out[0] = x;
  out[1] = y;
  out[2] = z;
}

/// out = Exp(w) p: rotates p by the rotation vector w (radians) by Rodrigues' formula
///   Exp(w) p = p + a w x p + b w x (w x p),  a = sin(theta) / theta,  b = (1 - cos(theta)) /
///   theta^2,
/// with a and b from their Taylor series below theta = |w| = 1e-3 rad, where the closed forms lose
/// precision (out may alias p).
template <typename T>
void angle_axis_rotate(const T w[3], const T p[3], T out[3]) {
  T a, b;
  angle_axis_coefficients(w, &a, &b);
  angle_axis_rotate(w, a, b, p, out);
}

/// A rigid transform templated on the scalar: p_to = R p_from + t.
template <typename T>
struct Pose {
  Eigen::Matrix<T, 3, 3> R = Eigen::Matrix<T, 3, 3>::Identity();  ///< rotation
  Eigen::Matrix<T, 3, 1> t = Eigen::Matrix<T, 3, 1>::Zero();      ///< translation (metres)

  /// From carat's SE(3) storage [qx, qy, qz, qw, tx, ty, tz] (q need not be normalized).
  static Pose from_storage(const T* x) {
    using std::sqrt;
    const T n = sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2] + x[3] * x[3]);
    const T qx = x[0] / n, qy = x[1] / n, qz = x[2] / n, qw = x[3] / n;
    Pose out;
    const T one(1.0), two(2.0);
    out.R << one - two * (qy * qy + qz * qz), two * (qx * qy - qw * qz), two * (qx * qz + qw * qy),
        two * (qx * qy + qw * qz), one - two * (qx * qx + qz * qz), two * (qy * qz - qw * qx),
        two * (qx * qz - qw * qy), two * (qy * qz + qw * qx), one - two * (qx * qx + qy * qy);
    out.t << x[4], x[5], x[6];
    return out;
  }
  /// Exp of the SE(3) tangent xi = [omega, v].
  static Pose exp(const T xi[6]) {
    using std::cos;
    using std::sin;
    using std::sqrt;
    const T theta_sq = xi[0] * xi[0] + xi[1] * xi[1] + xi[2] * xi[2];
    Eigen::Matrix<T, 3, 3> W;
    W << T(0.0), -xi[2], xi[1], xi[2], T(0.0), -xi[0], -xi[1], xi[0], T(0.0);
    T a, b, c;  // R = I + a W + b W^2, V = I + b W + c W^2
    if (value_of(theta_sq) > 1e-16) {
      const T theta = sqrt(theta_sq);
      a = sin(theta) / theta;
      b = (T(1.0) - cos(theta)) / theta_sq;
      c = (theta - sin(theta)) / (theta_sq * theta);
    } else {
      a = T(1.0) - theta_sq / T(6.0);
      b = T(0.5) - theta_sq / T(24.0);
      c = T(1.0 / 6.0) - theta_sq / T(120.0);
    }
    const Eigen::Matrix<T, 3, 3> W2 = W * W;
    Pose out;
    out.R = Eigen::Matrix<T, 3, 3>::Identity() + a * W + b * W2;
    const Eigen::Matrix<T, 3, 3> V = Eigen::Matrix<T, 3, 3>::Identity() + b * W + c * W2;
    out.t = V * Eigen::Matrix<T, 3, 1>(xi[3], xi[4], xi[5]);
    return out;
  }
  /// R p + t, for a point of this scalar or of plain doubles (a point that is data: then no
  /// derivative of it is carried along, which makes a functor several times cheaper).
  template <typename Derived>
  Eigen::Matrix<T, 3, 1> act(const Eigen::MatrixBase<Derived>& p) const {
    Eigen::Matrix<T, 3, 1> out;
    for (int i = 0; i < 3; ++i) out[i] = R(i, 0) * p[0] + R(i, 1) * p[1] + R(i, 2) * p[2] + t[i];
    return out;
  }
  /// This transform, then `other` first: (this * other)(p) = this(other(p)).
  Pose operator*(const Pose& other) const {
    Pose out;
    out.R = R * other.R;
    out.t = R * other.t + t;
    return out;
  }
  /// The inverse transform (R^T, -R^T t).
  Pose inverse() const {
    Pose out;
    out.R = R.transpose();
    out.t = -(out.R * t);
    return out;
  }
};

}  // namespace carat::lie
