#pragma once

/// Point-to-point ICP rows over fixed correspondences: r_k = mu_target_k - T_ij mu_source_k
/// (three rows per pair, metres). Variables: target pose T_world_i, source pose T_world_j;
/// reduced Jacobian w.r.t. the tangent of T_ij (see registration_rows.hpp). 48 bytes per pair.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <memory>
#include <span>
#include <vector>

#include "carat/residuals/pose_gram.hpp"
#include "carat/solver/residual_block.hpp"

namespace carat {

/// Three unweighted rows per correspondence.
class PointToPointBlock final : public ResidualBlock, public AffinePoseRows {
 public:
  /// points_target[k] pairs with points_source[k]. Throws carat::Error for no pairs, different
  /// lengths or non-finite values.
  PointToPointBlock(std::span<const Eigen::Vector3d> points_target,
                    std::span<const Eigen::Vector3d> points_source);

  int num_rows() const override {
    return static_cast<int>(rows_.empty() ? 3 * target_.size() : rows_.size());
  }
  std::span<const int> tangent_dims() const override { return kDims; }
  int reduced_dim() const override { return 6; }
  void reduced_map(ParameterPointers params, double* A) const override;
  void evaluate_rows(ParameterPointers params, std::span<const int> rows, double* residuals,
                     double* jacobian) const override;
  std::unique_ptr<ResidualBlock> extract_rows(std::span<const int> rows) const override;
  std::size_t memory_bytes() const override;
  PoseGram pose_gram(const Eigen::Isometry3d& T_target_source_reference) const override;
  /// The lossless rows about the relative pose of `params` (lossless_form()).
  std::shared_ptr<const ResidualBlock> exact_form(ParameterPointers params) const override;

 private:
  PointToPointBlock() = default;
  static constexpr std::array<int, 2> kDims{6, 6};
  std::vector<Eigen::Vector3d> target_;
  std::vector<Eigen::Vector3d> source_;
  std::vector<int> rows_;  // empty: row 3k+c; else (pair << 2) | component
};

}  // namespace carat
