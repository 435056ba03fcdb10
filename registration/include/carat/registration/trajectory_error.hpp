#pragma once

/// Absolute trajectory error (ATE) of an estimated trajectory against a reference, as evo's APE
/// reports its translation part: optional rigid Umeyama alignment of the estimate onto the
/// reference, then statistics of |t_ref_k - t_aligned_est_k| (and of the rotation angles), with
/// the pose-pairing step (by stamp) that TUM trajectories need first.

#include <Eigen/Geometry>
#include <span>
#include <utility>
#include <vector>

namespace carat {

/// Rigid alignment (rotation and translation, no scale; Umeyama 1991) minimizing
/// sum_k |T * estimate_k - reference_k|^2: returns T = T_reference_estimate. Throws carat::Error
/// for fewer than 3 pairs, mismatched lengths or non-finite points. When the minimizer is not
/// unique (all points collinear: the rotation about the line is free; or all coincident) one of
/// the minimizing rotations is returned, always a proper finite rotation (identity when the
/// cross-covariance vanishes).
Eigen::Isometry3d align_umeyama(std::span<const Eigen::Vector3d> estimate,
                                std::span<const Eigen::Vector3d> reference);

/// Statistics of the ATE: translation errors in metres, rotation errors in degrees.
struct AteStatistics {
  double rmse = 0.0;    ///< sqrt(mean(e_k^2)), e_k = |t_ref_k - t_aligned_est_k|
  double mean = 0.0;    ///< mean of e_k
  double median = 0.0;  ///< median of e_k (mean of the two middle values for an even count)
  double std = 0.0;     ///< population standard deviation of e_k (as numpy and evo)
  double min = 0.0;     ///< smallest e_k
  double max = 0.0;     ///< largest e_k
  double rotation_rmse_deg = 0.0;  ///< RMS of the angles of R_ref_k^T R_aligned_est_k (degrees)
  double rotation_mean_deg = 0.0;  ///< mean of those angles (degrees)
  double rotation_max_deg = 0.0;   ///< largest of those angles (degrees)
  int num_poses = 0;               ///< number of pose pairs evaluated
  Eigen::Isometry3d T_reference_estimate =
      Eigen::Isometry3d::Identity();  ///< alignment applied to the estimate (identity if none)
};

/// Settings of compute_ate().
struct AteOptions {
  bool align = true;  ///< align the estimate onto the reference with align_umeyama() first; when
                      ///< the estimate's positions lie on a line (or coincide) the rotation about
                      ///< them, which positions cannot fix, is the one that best aligns the
                      ///< orientations
};

/// ATE of `estimate` against `reference` (pose k of one corresponds to pose k of the other).
/// Throws carat::Error on a length mismatch (naming both counts), empty input, non-finite poses,
/// fewer than 3 poses when aligning, or a translation error that overflows (coordinates ~1e154+).
AteStatistics compute_ate(std::span<const Eigen::Isometry3d> estimate,
                          std::span<const Eigen::Isometry3d> reference,
                          const AteOptions& options = {});

/// Pairs poses by stamp: candidate pairs differ by at most `max_difference` (seconds), the
/// closest candidates are taken first (ties: lower estimate index, then lower reference index)
/// and each pose is used at most once. Returns (estimate index, reference index) pairs sorted by
/// estimate index. Stamps need not be sorted or distinct. Throws carat::Error for non-finite
/// stamps or a negative or non-finite max_difference.
///
/// Exactly: with differences |estimate_stamp - reference_stamp| as rounded in double, the result
/// is that of scanning all candidates in increasing (difference, estimate index, reference index)
/// and taking each whose two poses are both still unused, for every input (equal stamps and equal
/// differences included); the candidates are never listed. O((n + m) log(n + m)) time and
/// O(n + m) memory for n estimate and m reference stamps, whatever `max_difference`.
std::vector<std::pair<int, int>> associate_by_stamp(std::span<const double> estimate_stamps,
                                                    std::span<const double> reference_stamps,
                                                    double max_difference = 0.01);

}  // namespace carat
