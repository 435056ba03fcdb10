#pragma once

/// The Gram matrix of registration rows that are affine in the entries of the relative pose.
///
/// Every row of carat's binary registration blocks (GICP with its whitening fixed when the block
/// is built, point-to-plane, point-to-point) has the form r_k = l_k . (mu_target_k - R mu_source_k
/// - t) for T_ij = (R, t): affine in the twelve entries of T_ij. With a reference pose
/// (R_ref, t_ref) and a centre c of the source points, write
///
///   y(T_ij) = [vec(R - R_ref) (9, column-major); (t - t_ref) + (R - R_ref) c (3); 1]  (13),
///
/// so r_k(T_ij) = g_k . y(T_ij) with g_k = [-(p_k (x) l_k); -l_k; r_k(T_ref)], p_k = mu_source_k
/// - c ((p (x) l)[a + 3b] = l_a p_b). Then sum_k r_k^2 = y^T G y with G = sum_k g_k g_k^T, at every
/// relative pose, not only near the reference: 91 numbers hold the block's whole cost function.
/// The reference and the centre only condition the numbers (y is small near the reference, and
/// the rotation columns use points relative to their centre).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>

namespace carat {

/// The affine embedding y(T_ij) of relative poses about a reference pose and a source centre.
struct PoseEmbedding {
  Eigen::Matrix3d R_target_source_reference = Eigen::Matrix3d::Identity();  ///< R_ref
  Eigen::Vector3d t_target_source_reference = Eigen::Vector3d::Zero();      ///< t_ref (metres)
  Eigen::Vector3d source_centre = Eigen::Vector3d::Zero();  ///< c, source frame (metres)

  /// The embedding about T_target_source_reference with the given source centre.
  static PoseEmbedding about(const Eigen::Isometry3d& T_target_source_reference,
                             const Eigen::Vector3d& source_centre);
  /// y(T_target_source) (13).
  Eigen::Matrix<double, 13, 1> value(const Eigen::Isometry3d& T_target_source) const;
  /// dy/dxi (13 x 6) at T_target_source for the right perturbation T <- T Exp(xi),
  /// xi = [omega, v].
  Eigen::Matrix<double, 13, 6> jacobian(const Eigen::Isometry3d& T_target_source) const;
};

/// A block's rows summed into the Gram matrix of their coefficients in y(T_ij) (see above).
struct PoseGram {
  Eigen::Matrix<double, 13, 13> gram = Eigen::Matrix<double, 13, 13>::Zero();  ///< G (symmetric)
  PoseEmbedding embedding;  ///< the y(T_ij) whose coefficients G sums
  std::size_t rows = 0;     ///< number of rows summed into G
};

/// Implemented by registration blocks whose rows are affine in the entries of T_ij.
class AffinePoseRows {
 public:
  virtual ~AffinePoseRows() = default;

  /// The Gram matrix of every row the block holds, about T_target_source_reference, with the
  /// centre c at the mean of every 16th of the block's source points (it only conditions the
  /// numbers). Deterministic (fixed summation order).
  virtual PoseGram pose_gram(const Eigen::Isometry3d& T_target_source_reference) const = 0;
};

}  // namespace carat
