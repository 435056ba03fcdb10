#pragma once

/// SE(2) relative-pose residual between two planar poses T_world_i and T_world_j (2D pose
/// graphs).
///
/// Error (translation first, as in g2o's EDGE_SE2 information matrices):
///   [w, vx, vy] = Log(T_i_j_measured^-1 T_world_i^-1 T_world_j),   e = [vx, vy, w],
/// residual r = U e with U^T U = information (3 rows). Jacobians are with respect to the
/// right-perturbation tangents [omega, vx, vy] of both poses (analytic).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>

#include "carat/solver/residual_block.hpp"

namespace carat {

/// A measured planar relative pose T_i_j with its 3x3 information (x, y, theta order).
class RelativePoseSE2Block final : public ResidualBlock {
 public:
  /// T_i_j: the measured pose of j in i's frame (metres, radians); information: symmetric
  /// positive definite, rows and columns in the order x, y, theta. Throws carat::Error otherwise.
  RelativePoseSE2Block(const Eigen::Isometry2d& T_i_j, const Eigen::Matrix3d& information);

  int num_rows() const override { return 3; }
  std::span<const int> tangent_dims() const override { return kDims; }
  void evaluate_rows(ParameterPointers params, std::span<const int> rows, double* residuals,
                     double* jacobian) const override;
  double accumulate(ParameterPointers params, Eigen::Ref<Eigen::MatrixXd> H_r,
                    Eigen::Ref<Eigen::VectorXd> b_r) const override;
  double squared_norm(ParameterPointers params) const override;
  std::size_t memory_bytes() const override { return sizeof(*this); }

  /// The measured relative pose T_i_j.
  const Eigen::Isometry2d& measurement() const { return T_i_j_; }
  /// The upper-triangular square-root information U (U^T U = information; x, y, theta order).
  const Eigen::Matrix3d& sqrt_information() const { return sqrt_info_; }

  /// Whitened residual (3) and, if J is not null, its 3 x 6 Jacobian [d/d xi_i, d/d xi_j];
  /// pose_i and pose_j are SE(2) storages [x, y, theta].
  void evaluate(const double* pose_i, const double* pose_j, Eigen::Vector3d* r,
                Eigen::Matrix<double, 3, 6>* J) const;

 private:
  static constexpr std::array<int, 2> kDims{3, 3};
  Eigen::Isometry2d T_i_j_;
  Eigen::Isometry2d T_j_i_;
  Eigen::Matrix3d sqrt_info_;
};

}  // namespace carat
