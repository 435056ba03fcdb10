#pragma once

// Internal: the Gram matrix of affine registration rows (pose_gram.hpp), summed item by item.

#include <Eigen/Geometry>
#include <array>
#include <cstddef>

#include "carat/residuals/pose_gram.hpp"

namespace carat::internal {

/// Sums items into a PoseGram. An item is one row or the rows of one correspondence: with r0 each
/// row at the reference pose, it brings Omega = sum l l^T over its rows (upper triangle: 00 01 02
/// 11 12 22), its source point, w = sum l r0 and s = sum r0^2. Items go to kLanes lanes in turn,
/// each lane summing its own (so that the products of kLanes items are one vector operation each,
/// with the same bits for any vector width, given no fused multiply-adds where this is inlined:
/// the files that include it are built with -ffp-contract=off); every 256 items the lanes' sums
/// are added to the total in lane order (partial sums keep rounding lower than one long sum).
class PoseGramSum {
 public:
  /// Rows about T_target_source_reference, rotation columns about `source_centre`.
  PoseGramSum(const Eigen::Isometry3d& T_target_source_reference,
              const Eigen::Vector3d& source_centre);

  /// Adds one item of `rows` rows (inline: it is the body of the blocks' hot loops).
  [[gnu::always_inline]] void add(const std::array<double, 6>& omega,
                                  const std::array<double, 3>& source,
                                  const std::array<double, 3>& w, double s, int rows) {
    const int l = lane_;
    const double p0 = source[0] - c_[0], p1 = source[1] - c_[1], p2 = source[2] - c_[2];
    left_[0][l] = p0 * p0;
    left_[1][l] = p0 * p1;
    left_[2][l] = p0 * p2;
    left_[3][l] = p1 * p1;
    left_[4][l] = p1 * p2;
    left_[5][l] = p2 * p2;
    left_[6][l] = p0;
    left_[7][l] = p1;
    left_[8][l] = p2;
    for (int j = 0; j < 6; ++j) right_[j][l] = omega[static_cast<std::size_t>(j)];
    for (int j = 0; j < 3; ++j) right_[6 + j][l] = w[static_cast<std::size_t>(j)];
    right_[9][l] = s;
    rows_ += static_cast<std::size_t>(rows);
    if (++lane_ == kLanes) add_lanes();
  }

  /// The Gram matrix of every item added.
  PoseGram finish();

  /// T_ref mu for a source point mu (the reference pose in scalars).
  [[gnu::always_inline]] std::array<double, 3> apply_reference(
      const std::array<double, 3>& mu) const {
    return {r_[0] * mu[0] + r_[3] * mu[1] + r_[6] * mu[2] + t_[0],
            r_[1] * mu[0] + r_[4] * mu[1] + r_[7] * mu[2] + t_[1],
            r_[2] * mu[0] + r_[5] * mu[1] + r_[8] * mu[2] + t_[2]};
  }

 private:
  static constexpr int kLanes = 8;
  static constexpr int kChunk = 256;  // items between additions of the lanes to the total
  /// Adds the kLanes items held to the lanes' sums: only the products G needs, p p^T (x) Omega,
  /// p (x) [Omega, w] and [Omega, w, s] itself (73 sums a lane).
  [[gnu::always_inline]] void add_lanes() {
    for (int i = 0; i < 6; ++i) {
      for (int j = 0; j < 6; ++j) {
        for (int l = 0; l < kLanes; ++l) lanes_.pp_omega[i][j][l] += left_[i][l] * right_[j][l];
      }
    }
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 9; ++j) {
        for (int l = 0; l < kLanes; ++l) lanes_.p_right[i][j][l] += left_[6 + i][l] * right_[j][l];
      }
    }
    for (int j = 0; j < 10; ++j) {
      for (int l = 0; l < kLanes; ++l) lanes_.right[j][l] += right_[j][l];
    }
    lane_ = 0;
    if (++groups_ == kChunk / kLanes) flush();
  }
  void flush();  // adds the lanes' sums to total_ in lane order and clears them
  /// Sums over items, p = source - centre, right = [Omega (6), w (3), s], per lane.
  struct LaneSums {
    alignas(64) double pp_omega[6][6][kLanes] = {};  ///< (p p^T)_i Omega_j
    alignas(64) double p_right[3][9][kLanes] = {};   ///< p_i right_j (j < 9: p s is not needed)
    alignas(64) double right[10][kLanes] = {};       ///< right_j
  };
  /// The same sums over all lanes.
  struct Sums {
    double pp_omega[6][6] = {};  ///< (p p^T)_i Omega_j, p p^T as 00 01 02 11 12 22
    double p_right[3][9] = {};   ///< p_i right_j
    double right[10] = {};       ///< right_j
  };
  alignas(64) double left_[9][kLanes] = {};    // per lane: p p^T (6), p (3)
  alignas(64) double right_[10][kLanes] = {};  // per lane: Omega (6), w (3), s
  LaneSums lanes_;
  Sums total_;
  int lane_ = 0;
  int groups_ = 0;
  std::size_t rows_ = 0;
  double r_[9];
  double t_[3];
  double c_[3];
  PoseEmbedding embedding_;
};

/// The mean of every 16th of `count` points given by point(k) (k < count; k = 0, 16, 32, ...:
/// point 0 alone below 17 points), or zero when count is 0: a centre to condition the sums, which
/// reads 1/16 of the data.
template <class PointOf>
Eigen::Vector3d mean_point(std::size_t count, const PointOf& point) {
  constexpr std::size_t kStride = 16;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  std::size_t n = 0;
  for (std::size_t k = 0; k < count; k += kStride, ++n) sum += point(k);
  return n > 0 ? Eigen::Vector3d(sum / static_cast<double>(n)) : sum;
}

}  // namespace carat::internal
