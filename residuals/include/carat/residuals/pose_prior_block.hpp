#pragma once

/// SE(3) prior on one pose T_world_body:
///   e_t = R_p^T (t - t_p),   e_r = 2 vec(q_p^-1 q),   r = U e,  U^T U = information.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>

#include "carat/solver/residual_block.hpp"
#include "carat/solver/se3.hpp"

namespace carat {

/// Pulls one pose towards T_world_prior with a 6x6 information (translation first).
class PosePriorBlock final : public ResidualBlock {
 public:
  /// information must be symmetric positive definite; throws carat::Error otherwise.
  PosePriorBlock(const Eigen::Isometry3d& T_world_prior, const se3::Matrix6d& information);

  int num_rows() const override { return 6; }
  std::span<const int> tangent_dims() const override { return kDims; }
  void evaluate_rows(ParameterPointers params, std::span<const int> rows, double* residuals,
                     double* jacobian) const override;
  std::size_t memory_bytes() const override { return sizeof(*this); }

  /// Whitened residual and, if J is not null, its 6 x 6 Jacobian.
  void evaluate(const double* pose, Eigen::Matrix<double, 6, 1>* r,
                Eigen::Matrix<double, 6, 6>* J) const;

 private:
  static constexpr std::array<int, 1> kDims{6};
  Eigen::Quaterniond q_prior_inverse_;
  Eigen::Vector3d t_prior_;
  Eigen::Matrix3d R_prior_transpose_;
  se3::Matrix6d sqrt_info_;
};

/// Upper-triangular U with U^T U = information; throws carat::Error (prefixed by `what`) if the
/// matrix is not finite, symmetric and positive definite.
se3::Matrix6d sqrt_information(const se3::Matrix6d& information, const char* what);

/// The same for a 3x3 information matrix (planar poses, x, y, theta order).
Eigen::Matrix3d sqrt_information(const Eigen::Matrix3d& information, const char* what);

}  // namespace carat
