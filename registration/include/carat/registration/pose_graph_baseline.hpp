#pragma once

/// The pose-graph baseline of global registration: one SE(3) relative-pose factor per
/// registered frame pair, with identity or GICP-Hessian information and a Cauchy kernel.

#include <Eigen/Geometry>
#include <cstddef>
#include <span>
#include <string_view>
#include <vector>

#include "carat/registration/pair_registration.hpp"
#include "carat/solver/se3.hpp"
#include "carat/solver/solver_options.hpp"
#include "carat/solver/solver_summary.hpp"

namespace carat {

/// Information matrix of each relative-pose factor.
enum class PoseGraphInformation {
  kIdentity,  ///< every factor weighs the same
  kHessian,   ///< the GICP Hessian of the pair at its alignment
};

/// Name of an information setting: "identity" or "hessian".
const char* to_string(PoseGraphInformation information);
/// Parses "identity" or "hessian"; throws carat::Error listing them otherwise.
PoseGraphInformation parse_pose_graph_information(std::string_view name);

/// Settings of optimize_pose_graph_baseline().
struct PoseGraphBaselineOptions {
  PoseGraphInformation information = PoseGraphInformation::kHessian;  ///< factor weights
  /// Cauchy kernel scale on the whitened error; 0 disables it. With Hessian information the
  /// whitened errors of good pairs are far above 1, so a scale of 1 down-weights every factor
  /// by about 1 / |error|^2 (a strong reweighting, not only outlier rejection).
  double cauchy_scale = 1.0;
  SolverOptions solver;  ///< LM settings (first pose held constant)
  /// After the solve: every pose's marginal covariance at the solution (carat::Covariance).
  bool covariance = false;
};

/// Optimized poses and the solve's summary.
struct PoseGraphBaselineResult {
  std::vector<Eigen::Isometry3d> T_world_frame;  ///< optimized poses
  SolverSummary summary;                         ///< the solve
  std::size_t unconverged_pairs = 0;  ///< registrations that did not converge (kept as factors)
  /// With PoseGraphBaselineOptions::covariance: per frame, the covariance of its pose's right
  /// perturbation xi = [omega (rad), v (m)], T_world_frame <- T_world_frame Exp(xi); zero for
  /// the first frame, which is held constant.
  std::vector<se3::Matrix6d> covariance;
  double covariance_s = 0.0;  ///< wall time of the covariances
};

/// The information of a relative-pose factor (translation first, RelativePoseBlock's order)
/// equivalent to a GICP Hessian H over the right tangent [w, v] of T_target_source, plus a
/// ridge of 1e-9 x its largest diagonal entry so that a degenerate pair stays usable.
se3::Matrix6d relative_pose_information(const Eigen::Isometry3d& T_target_source,
                                        const se3::Matrix6d& H);

/// Optimizes the poses from T_world_initial with one factor per registration (those that did not
/// converge too: the kernel down-weights them; they are counted in unconverged_pairs). Throws
/// carat::Error when a frame is tied to frame 0 only through registrations that did not converge
/// (it would land where they put it, the solve reporting convergence; the pairs are named), when
/// a registration names a missing frame or has information that is not positive definite, when a
/// frame is tied to no fixed one, or when the solve fails.
PoseGraphBaselineResult optimize_pose_graph_baseline(
    std::span<const Eigen::Isometry3d> T_world_initial,
    std::span<const PairRegistration> registrations, const PoseGraphBaselineOptions& options = {});

}  // namespace carat
