#include "carat/residuals/snavely_block.hpp"

#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>

#include "angle_axis_terms.hpp"
#include "carat/base/error.hpp"
#include "carat/residuals/snavely_camera.hpp"

namespace carat {
namespace {

/// The angle-axis terms of the cameras this thread evaluated last. A camera's rotation is the
/// same for each of its many observations in a pass, so it is computed once per pass and
/// camera rather than once per observation. A slot is keyed by the camera's address and
/// checked against its three angle-axis values bit for bit: a hit gives exactly the terms that
/// computing them would.
class TermsCache {
 public:
  /// The terms of the camera at `camera` (its first three values, w).
  [[gnu::always_inline]] const internal::AngleAxisTerms& terms(const double* camera) {
    Slot& slot = slots_[(reinterpret_cast<std::uintptr_t>(camera) / sizeof(double)) % kSlots];
    if (slot.camera != camera || std::memcmp(slot.w, camera, sizeof(slot.w)) != 0) {
      slot.terms = internal::angle_axis_terms(Eigen::Map<const Eigen::Vector3d>(camera));
      std::memcpy(slot.w, camera, sizeof(slot.w));
      slot.camera = camera;
    }
    return slot.terms;
  }

 private:
  /// Slots (cameras stored 9 doubles apart fall in distinct slots, 128 cameras in a row).
  static constexpr std::size_t kSlots = 128;
  struct Slot {
    const double* camera = nullptr;
    double w[3] = {0.0, 0.0, 0.0};
    internal::AngleAxisTerms terms;
  };
  std::array<Slot, kSlots> slots_;
};

thread_local TermsCache t_terms_cache;

}  // namespace

SnavelyReprojectionBlock::SnavelyReprojectionBlock(double observed_x, double observed_y,
                                                   BalCameraTangent camera_tangent)
    : observed_(observed_x, observed_y), camera_tangent_(camera_tangent) {
  if (!std::isfinite(observed_x) || !std::isfinite(observed_y)) {
    throw Error("SnavelyReprojectionBlock: observation (" + message_number(observed_x) + ", " +
                message_number(observed_y) + ") is not finite");
  }
}

Eigen::Vector2d SnavelyReprojectionBlock::evaluate(const double* camera, const double* point,
                                                   Jacobian* jacobian) const {
  const Eigen::Map<const Eigen::Vector3d> t(camera + 3);
  const Eigen::Map<const Eigen::Vector3d> X(point);
  const double f = camera[6], k1 = camera[7], k2 = camera[8];

  const internal::AngleAxisTerms& terms = t_terms_cache.terms(camera);
  const Eigen::Matrix3d& R = terms.R;
  const Eigen::Vector3d P = R * X + t;

  const double inverse_z = 1.0 / P.z();
  const Eigen::Vector2d p(-P.x() * inverse_z, -P.y() * inverse_z);
  const double r2 = p.squaredNorm();
  const double distortion = 1.0 + r2 * (k1 + k2 * r2);
  const Eigen::Vector2d residual = f * distortion * p - observed_;
  if (jacobian == nullptr) return residual;

  // d image / d p = f (d I + 2 (k1 + 2 k2 r2) p p^T);  d p / d P = -1/P_z [I | p].
  const Eigen::Matrix2d d_image_d_p = f * (distortion * Eigen::Matrix2d::Identity() +
                                           (2.0 * (k1 + 2.0 * k2 * r2)) * p * p.transpose());
  Eigen::Matrix<double, 2, 3> d_p_d_P;
  d_p_d_P << 1.0, 0.0, p.x(), 0.0, 1.0, p.y();
  d_p_d_P *= -inverse_z;
  const Eigen::Matrix<double, 2, 3> d_image_d_P = d_image_d_p * d_p_d_P;
  const Eigen::Matrix<double, 2, 3> d_image_d_X = d_image_d_P * R;
  if (camera_tangent_ == BalCameraTangent::kParameters) {
    // d (R(w) X) / d w = -R [X]x J_r(w).
    jacobian->block<2, 3>(0, 0).noalias() = -(d_image_d_X * internal::cross_matrix(X)) * terms.J_r;
    jacobian->block<2, 3>(0, 3) = d_image_d_P;
  } else {
    // P = R(w) (X - c) with the centre c held while w steps: d P / d dw = -R [X - c]x J_r(w),
    // where X - c = R^T P; d P / d dc = -R.
    const Eigen::Vector3d from_centre = R.transpose() * P;
    jacobian->block<2, 3>(0, 0).noalias() =
        -(d_image_d_X * internal::cross_matrix(from_centre)) * terms.J_r;
    jacobian->block<2, 3>(0, 3) = -d_image_d_X;
  }
  jacobian->col(6) = distortion * p;
  jacobian->col(7) = (f * r2) * p;
  jacobian->col(8) = (f * r2 * r2) * p;
  jacobian->block<2, 3>(0, 9) = d_image_d_X;
  return residual;
}

void SnavelyReprojectionBlock::evaluate_rows(ParameterPointers params, std::span<const int> rows,
                                             double* residuals, double* jacobian) const {
  Jacobian J;
  const Eigen::Vector2d r = evaluate(params[0], params[1], jacobian ? &J : nullptr);
  for (std::size_t k = 0; k < rows.size(); ++k) {
    const int row = rows[k];
    residuals[k] = r[row];
    if (jacobian) {
      for (int col = 0; col < 12; ++col)
        jacobian[12 * k + static_cast<std::size_t>(col)] = J(row, col);
    }
  }
}

double SnavelyReprojectionBlock::accumulate(ParameterPointers params,
                                            Eigen::Ref<Eigen::MatrixXd> H_r,
                                            Eigen::Ref<Eigen::VectorXd> b_r) const {
  Jacobian J;
  const Eigen::Vector2d r = evaluate(params[0], params[1], &J);
  // J^T J is symmetric: form its upper triangle once and add it to both halves.
  for (int j = 0; j < 12; ++j) {
    const double a0 = J(0, j), a1 = J(1, j);
    for (int i = 0; i < j; ++i) {
      const double h = J(0, i) * a0 + J(1, i) * a1;
      H_r(i, j) += h;
      H_r(j, i) += h;
    }
    H_r(j, j) += a0 * a0 + a1 * a1;
    b_r(j) += a0 * r.x() + a1 * r.y();
  }
  return r.squaredNorm();
}

double SnavelyReprojectionBlock::squared_norm(ParameterPointers params) const {
  // The residual as linearizations form it, with the camera's rotation from the thread's cache.
  return evaluate(params[0], params[1], nullptr).squaredNorm();
}

}  // namespace carat
