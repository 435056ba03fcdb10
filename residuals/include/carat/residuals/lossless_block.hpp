#pragma once

/// A binary registration block rewritten losslessly as at most 13 rows.
///
/// The rows of carat's registration blocks are affine in the entries of the relative pose, so a
/// block's whole cost is y(T_ij)^T G y(T_ij) with G its 13 x 13 Gram matrix (pose_gram.hpp).
/// Factoring G = V^T V (pivoted Cholesky of G scaled to a unit diagonal, V upper triangular in
/// the pivot order) gives rows r = V y(T_ij) with the same cost, gradient and Gauss-Newton Hessian
/// as the original block at *every* relative pose, up to rounding, where an exact coreset matches
/// them at its evaluation point only. The factor ends when the largest remaining diagonal of the
/// scaled G (a squared pivot) is at most 1e-13: the rows then number the numerical rank of G,
/// and what they leave out is below rounding.
/// Memory: 91 doubles for V, the reference pose and centre (15 doubles) and the pivot order.
/// Variables: target pose T_world_i, source pose T_world_j; reduced Jacobian w.r.t. the tangent
/// of T_ij (see registration_rows.hpp).

#include <array>
#include <cstdint>
#include <memory>
#include <span>

#include "carat/residuals/pose_gram.hpp"
#include "carat/solver/residual_block.hpp"

namespace carat {

namespace internal {
class BlockCodec;  // block_serialization.cpp: reads and writes the private state
}  // namespace internal

/// At most 13 rows with the cost function of the block whose Gram matrix they factor.
class LosslessRegistrationBlock final : public ResidualBlock {
 public:
  /// Factors gram.gram. Throws carat::Error if it, its reference pose or its centre is not
  /// finite, if it is zero or not symmetric, or if it is not positive semidefinite (a negative
  /// diagonal, a zero diagonal whose row is not zero, or a remaining diagonal below -1e-9 after
  /// scaling to a unit diagonal).
  explicit LosslessRegistrationBlock(const PoseGram& gram);

  int num_rows() const override { return rank_; }
  std::span<const int> tangent_dims() const override { return kDims; }
  int reduced_dim() const override { return 6; }
  void reduced_map(ParameterPointers params, double* A) const override;
  void evaluate_rows(ParameterPointers params, std::span<const int> rows, double* residuals,
                     double* jacobian) const override;
  std::size_t memory_bytes() const override;

  /// Number of rows the original block had.
  std::size_t original_rows() const { return original_rows_; }

 private:
  friend class internal::BlockCodec;
  LosslessRegistrationBlock() = default;
  static constexpr std::array<int, 2> kDims{6, 6};
  /// Offset of row i's first entry in upper_: rows hold 13, 12, ..., entries.
  static constexpr int row_offset(int i) { return i * 13 - i * (i - 1) / 2; }
  PoseEmbedding embedding_;               // y(T_ij): reference pose and centre
  std::array<double, 91> upper_{};        // V's upper triangle, row by row, pivot order
  std::array<std::uint8_t, 13> order_{};  // pivot order: column j of V is coordinate order_[j]
  int rank_ = 0;
  std::size_t original_rows_ = 0;
};

/// The lossless rows of a block whose rows are affine in T_ij, about T_target_source_reference.
std::shared_ptr<const LosslessRegistrationBlock> make_lossless_block(
    const AffinePoseRows& block, const Eigen::Isometry3d& T_target_source_reference);

/// The lossless rows of a block whose rows are affine in T_ij, about the relative pose of
/// `params` (target pose T_world_i, source pose T_world_j): what such blocks return from
/// ResidualBlock::exact_form(). Throws carat::Error as LosslessRegistrationBlock's constructor.
std::shared_ptr<const ResidualBlock> lossless_form(const AffinePoseRows& block,
                                                   ParameterPointers params);

}  // namespace carat
