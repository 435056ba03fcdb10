#pragma once

/// SE(3) relative-pose residual between two poses T_world_i and T_world_j (pose graphs).
///
/// Error (translation first, as in g2o's information matrices and Ceres's pose_graph_3d):
///   e_t = R_i^T (t_j - t_i) - t_ij,   e_r = 2 vec(q_ij^-1 q_i^-1 q_j),
/// residual r = U e with U^T U = information (6 rows). Jacobians are with respect to the
/// right-perturbation tangents [omega, v] of both poses (analytic).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>

#include "carat/solver/residual_block.hpp"
#include "carat/solver/se3.hpp"

namespace carat {

/// A measured relative pose T_i_j with its 6x6 information (translation first).
class RelativePoseBlock final : public ResidualBlock {
 public:
  /// T_i_j: the measured pose of j in i's frame; information: symmetric positive definite
  /// (translation rows/columns first). Throws carat::Error otherwise.
  RelativePoseBlock(const Eigen::Isometry3d& T_i_j, const se3::Matrix6d& information);

  int num_rows() const override { return 6; }
  std::span<const int> tangent_dims() const override { return kDims; }
  void evaluate_rows(ParameterPointers params, std::span<const int> rows, double* residuals,
                     double* jacobian) const override;
  double accumulate(ParameterPointers params, Eigen::Ref<Eigen::MatrixXd> H_r,
                    Eigen::Ref<Eigen::VectorXd> b_r) const override;
  double squared_norm(ParameterPointers params) const override;
  std::size_t memory_bytes() const override { return sizeof(*this); }

  /// The measured relative pose.
  Eigen::Isometry3d measurement() const { return se3::make(q_ij_, t_ij_); }
  /// The upper-triangular square-root information U (U^T U = information).
  const se3::Matrix6d& sqrt_information() const { return sqrt_info_; }

  /// Whitened residual (6) and, if J is not null, its 6 x 12 Jacobian [d/d xi_i, d/d xi_j].
  void evaluate(const double* pose_i, const double* pose_j, Eigen::Matrix<double, 6, 1>* r,
                Eigen::Matrix<double, 6, 12>* J) const;

 private:
  static constexpr std::array<int, 2> kDims{6, 6};
  Eigen::Quaterniond q_ij_;
  Eigen::Vector3d t_ij_;
  Eigen::Matrix3d R_ij_transpose_;
  se3::Matrix6d sqrt_info_;
};

}  // namespace carat
