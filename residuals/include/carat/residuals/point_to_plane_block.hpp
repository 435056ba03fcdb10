#pragma once

/// Point-to-plane ICP rows over fixed correspondences: r_k = n_k . (mu_target_k - T_ij
/// mu_source_k), one row per pair (metres along the target normal n_k, unit length).
/// Variables: target pose T_world_i, source pose T_world_j; reduced Jacobian w.r.t. the tangent
/// of T_ij (see registration_rows.hpp). 72 bytes per pair.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <memory>
#include <span>
#include <vector>

#include "carat/residuals/pose_gram.hpp"
#include "carat/solver/residual_block.hpp"

namespace carat {

/// One row per correspondence.
class PointToPlaneBlock final : public ResidualBlock, public AffinePoseRows {
 public:
  /// Parallel arrays; normals are normalized here. Throws carat::Error for no pairs, different
  /// lengths, non-finite values or a zero normal.
  PointToPlaneBlock(std::span<const Eigen::Vector3d> points_target,
                    std::span<const Eigen::Vector3d> normals_target,
                    std::span<const Eigen::Vector3d> points_source);

  int num_rows() const override { return static_cast<int>(target_.size()); }
  std::span<const int> tangent_dims() const override { return kDims; }
  int reduced_dim() const override { return 6; }
  void reduced_map(ParameterPointers params, double* A) const override;
  void evaluate_rows(ParameterPointers params, std::span<const int> rows, double* residuals,
                     double* jacobian) const override;
  std::unique_ptr<ResidualBlock> extract_rows(std::span<const int> rows) const override;
  /// The rows with sqrt(w) folded into their normals (72 bytes a row, no weight kept).
  std::unique_ptr<ResidualBlock> extract_weighted_rows(
      std::span<const int> rows, std::span<const double> weights) const override;
  std::size_t memory_bytes() const override;
  PoseGram pose_gram(const Eigen::Isometry3d& T_target_source_reference) const override;
  /// The lossless rows about the relative pose of `params` (lossless_form()).
  std::shared_ptr<const ResidualBlock> exact_form(ParameterPointers params) const override;

 private:
  PointToPlaneBlock() = default;
  /// Rows `rows` (normals scaled by sqrt(weights[k]) unless weights is empty).
  std::unique_ptr<PointToPlaneBlock> extract_scaled(std::span<const int> rows,
                                                    std::span<const double> weights) const;
  static constexpr std::array<int, 2> kDims{6, 6};
  std::vector<Eigen::Vector3d> target_;
  std::vector<Eigen::Vector3d> normal_;
  std::vector<Eigen::Vector3d> source_;
};

}  // namespace carat
