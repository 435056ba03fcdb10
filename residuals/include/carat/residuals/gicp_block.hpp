#pragma once

/// The GICP registration error over fixed correspondences (Koide et al. 2023, Sec. III): for
/// correspondence k, three whitened rows r_k = W_k (mu_target_k - T_ij mu_source_k) with
/// W_k^T W_k = (C_target_k + R C_source_k R^T)^-1. The fused covariance uses the rotation R of
/// T_ij *when the block is built* (the estimate at which correspondences were found) and stays
/// fixed afterwards, so rows are exact functions of T_ij with exact Jacobians; scan matching
/// rebuilds blocks as its estimate moves. Variables: target pose T_world_i, source pose
/// T_world_j. Memory: 12 doubles (96 bytes) per correspondence; an extract of single rows (the
/// rows a coreset keeps) holds 7 doubles (56 bytes) per row instead: the whitening row l,
/// l . mu_target and mu_source (a weighted extract folds sqrt(w) into l and l . mu_target). An
/// extract of whole correspondences keeps them whole.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "carat/residuals/pose_gram.hpp"
#include "carat/solver/residual_block.hpp"

namespace carat {

namespace internal {
class BlockCodec;  // block_serialization.cpp: reads and writes the private state
}  // namespace internal

/// One GICP correspondence: a target point and a source point with their covariances.
struct GicpCorrespondence {
  Eigen::Vector3d mean_target;        ///< point in the target frame (metres)
  Eigen::Matrix3d covariance_target;  ///< its covariance
  Eigen::Vector3d mean_source;        ///< point in the source frame (metres)
  Eigen::Matrix3d covariance_source;  ///< its covariance
};

/// Three rows per correspondence; reduced Jacobian w.r.t. the tangent of T_ij (6 columns).
class GicpBlock final : public ResidualBlock, public AffinePoseRows {
 public:
  /// Builds the rows at the relative pose T_target_source (used only to fuse covariances).
  /// Throws carat::Error if there are no correspondences, a value is not finite, or a fused
  /// covariance is not positive definite.
  GicpBlock(std::span<const GicpCorrespondence> correspondences,
            const Eigen::Isometry3d& T_target_source);
  /// The same rows for the pairs (target index, source index) of two clouds held as float means
  /// and covariance upper triangles (xx xy xz yy yz zz), without a GicpCorrespondence per pair;
  /// built in parallel in the calling TBB arena (the rows do not depend on the thread count).
  /// Throws carat::Error as above (naming the first faulty pair), and for an index out of range.
  GicpBlock(std::span<const Eigen::Vector3f> target_means,
            std::span<const Eigen::Matrix<float, 6, 1>> target_covariances,
            std::span<const Eigen::Vector3f> source_means,
            std::span<const Eigen::Matrix<float, 6, 1>> source_covariances,
            std::span<const std::array<std::uint32_t, 2>> pairs,
            const Eigen::Isometry3d& T_target_source);

  int num_rows() const override {
    return static_cast<int>(rows_.empty() ? 3 * points_.size() : rows_.size());
  }
  std::span<const int> tangent_dims() const override { return kDims; }
  int reduced_dim() const override { return 6; }
  void reduced_map(ParameterPointers params, double* A) const override;
  void evaluate_rows(ParameterPointers params, std::span<const int> rows, double* residuals,
                     double* jacobian) const override;
  double accumulate(ParameterPointers params, Eigen::Ref<Eigen::MatrixXd> H_r,
                    Eigen::Ref<Eigen::VectorXd> b_r) const override;
  double squared_norm(ParameterPointers params) const override;
  std::unique_ptr<ResidualBlock> extract_rows(std::span<const int> rows) const override;
  /// Single rows with sqrt(w) folded into l and l . mu_target (56 bytes a row, no weight kept);
  /// null for whole correspondences in order, which keep their 96 bytes per three rows better.
  std::unique_ptr<ResidualBlock> extract_weighted_rows(
      std::span<const int> rows, std::span<const double> weights) const override;
  std::size_t memory_bytes() const override;
  PoseGram pose_gram(const Eigen::Isometry3d& T_target_source_reference) const override;
  /// The lossless rows about the relative pose of `params` (lossless_form()).
  std::shared_ptr<const ResidualBlock> exact_form(ParameterPointers params) const override;

  /// Number of correspondences held (0 for an extract, which holds single rows).
  int num_correspondences() const { return static_cast<int>(points_.size()); }

  /// H_r, b_r, c of all rows at a relative pose (the fast path, deterministic chunked sums).
  /// Covers the correspondences held: an extract of single rows holds none (its H_r, b_r, c
  /// come from accumulate(), which evaluates its rows).
  double accumulate_at(const Eigen::Isometry3d& T_target_source, Eigen::Matrix<double, 6, 6>* H_r,
                       Eigen::Matrix<double, 6, 1>* b_r) const;

 private:
  /// Per correspondence: target mean, source mean, whitening W (upper-triangular, 6 entries).
  struct Point {
    std::array<double, 3> target;
    std::array<double, 3> source;
    std::array<double, 6> whitening;  // W = [w0 w1 w2; 0 w3 w4; 0 0 w5]
  };
  /// One row of an extract: r = offset - l . (T mu_source), offset = l . mu_target, l a row of W.
  struct Row {
    std::array<double, 3> ell;
    double offset;
    std::array<double, 3> source;
  };
  friend class internal::BlockCodec;
  GicpBlock() = default;
  /// Row `row` of this block in the single-row form.
  Row row_of(int row) const;
  /// pose_gram() of a block holding these correspondences or rows.
  static PoseGram pose_gram_of(std::span<const Point> points, std::span<const Row> rows,
                               const Eigen::Isometry3d& T_target_source_reference);
  static constexpr std::array<int, 2> kDims{6, 6};
  std::vector<Point> points_;  // a full block: row 3k + c is component c of correspondence k
  std::vector<Row> rows_;      // an extract (points_ empty): row k is rows_[k]
};

}  // namespace carat
