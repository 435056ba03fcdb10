#pragma once

// Internal: the Gram matrix of affine registration rows (pose_gram.hpp), summed item by item.

#include <Eigen/Geometry>
#include <array>
#include <cstddef>

#include "carat/residuals/pose_gram.hpp"

namespace carat::internal {

/// Sums items into a PoseGram. An item is one row or the rows of one correspondence: with r0 each
/// row at the reference pose, it brings Omega = sum l l^T over its rows (upper triangle: 00 01 02
/// 11 12 22), its source point, w = sum l r0 and s = sum r0^2. Items are summed in chunks whose
/// totals are added in order (partial sums of 256 items keep rounding lower than one long sum).
class PoseGramSum {
 public:
  /// Rows about T_target_source_reference, rotation columns about `source_centre`.
  PoseGramSum(const Eigen::Isometry3d& T_target_source_reference,
              const Eigen::Vector3d& source_centre);

  /// Adds one item of `rows` rows (inline: it is the body of the blocks' hot loops).
  void add(const std::array<double, 6>& omega, const std::array<double, 3>& source,
           const std::array<double, 3>& w, double s, int rows) {
    const double p[3] = {source[0] - c_[0], source[1] - c_[1], source[2] - c_[2]};
    const double pp[6] = {p[0] * p[0], p[0] * p[1], p[0] * p[2],
                          p[1] * p[1], p[1] * p[2], p[2] * p[2]};
    const double right[10] = {omega[0], omega[1], omega[2], omega[3], omega[4],
                              omega[5], w[0],     w[1],     w[2],     s};
    // Only the products G needs: p p^T (x) Omega, p (x) [Omega, w] and [Omega, w, s] itself
    // (73 sums).
    for (int i = 0; i < 6; ++i) {
      for (int j = 0; j < 6; ++j) chunk_.pp_omega[i][j] += pp[i] * right[j];
    }
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 9; ++j) chunk_.p_right[i][j] += p[i] * right[j];
    }
    for (int j = 0; j < 10; ++j) chunk_.right[j] += right[j];
    rows_ += static_cast<std::size_t>(rows);
    if (++in_chunk_ == kChunk) flush();
  }

  /// The Gram matrix of every item added.
  PoseGram finish();

  /// T_ref mu for a source point mu (the reference pose in scalars).
  std::array<double, 3> apply_reference(const std::array<double, 3>& mu) const {
    return {r_[0] * mu[0] + r_[3] * mu[1] + r_[6] * mu[2] + t_[0],
            r_[1] * mu[0] + r_[4] * mu[1] + r_[7] * mu[2] + t_[1],
            r_[2] * mu[0] + r_[5] * mu[1] + r_[8] * mu[2] + t_[2]};
  }

 private:
  static constexpr int kChunk = 256;
  void flush();
  /// Sums over items, p = source - centre, right = [Omega (6), w (3), s].
  struct Sums {
    double pp_omega[6][6] = {};  ///< (p p^T)_i Omega_j, p p^T as 00 01 02 11 12 22
    double p_right[3][9] = {};   ///< p_i right_j (j < 9: p s is not needed)
    double right[10] = {};       ///< right_j
  };
  Sums chunk_;
  Sums total_;
  int in_chunk_ = 0;
  std::size_t rows_ = 0;
  double r_[9];
  double t_[3];
  double c_[3];
  PoseEmbedding embedding_;
};

/// The mean of `count` points given by point(k) (k < count), or zero when count is 0.
template <class PointOf>
Eigen::Vector3d mean_point(std::size_t count, const PointOf& point) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (std::size_t k = 0; k < count; ++k) sum += point(k);
  return count > 0 ? Eigen::Vector3d(sum / static_cast<double>(count)) : sum;
}

}  // namespace carat::internal
