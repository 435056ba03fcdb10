#pragma once

/// Scan matching: align a source cloud to a target cloud with GICP (or point-to-plane /
/// point-to-point ICP), re-searching correspondences at every iteration and taking each step
/// with carat's solver on the matching residual block.

#include <Eigen/Geometry>
#include <string_view>

#include "carat/registration/kdtree.hpp"
#include "carat/registration/point_cloud.hpp"
#include "carat/solver/se3.hpp"

namespace carat {

/// The registration error align() minimizes.
enum class RegistrationMethod {
  kGicp,          ///< GICP: Mahalanobis distance with fused plane-like covariances
  kPointToPlane,  ///< distance along the target normal (smallest eigenvector of its covariance)
  kPointToPoint,  ///< Euclidean distance
};

/// Name of a registration method: "gicp", "point-to-plane" or "point-to-point".
const char* to_string(RegistrationMethod method);
/// Parses "gicp", "point-to-plane" or "point-to-point"; throws carat::Error listing them
/// otherwise.
RegistrationMethod parse_registration_method(std::string_view name);

/// Settings of align().
struct AlignSettings {
  RegistrationMethod method = RegistrationMethod::kGicp;  ///< error to minimize
  double max_correspondence_distance = 1.0;               ///< metres; farther pairs are not used
  int max_iterations = 30;              ///< outer iterations (correspondence searches)
  double translation_tolerance = 1e-4;  ///< converged when a step moves less (metres) ...
  double rotation_tolerance = 1e-4;     ///< ... and turns less (radians)
  int min_correspondences = 29;         ///< fewer pairs than this is a failure (as few points as
                                        ///< preprocess_frame() accepts)
  int num_threads = 1;                  ///< threads for the search and the linearization
};

/// What align() found.
struct AlignResult {
  Eigen::Isometry3d T_target_source = Eigen::Isometry3d::Identity();  ///< maps source into target
  se3::Matrix6d H =
      se3::Matrix6d::Zero();    ///< J^T J of the method's rows at the result (right tangent of T)
  double error = 0.0;           ///< sum of squared residuals of the method's rows at the result
  int iterations = 0;           ///< outer iterations run
  int num_correspondences = 0;  ///< pairs used in the last iteration
  bool converged = false;       ///< the last step was below both tolerances
  int constrained_dof = 0;      ///< directions the geometry constrains (6 unless degenerate): the
                                ///< eigenvalues of H, rotations scaled by the source's RMS radius,
                                ///< above 5e-3 x the largest
  double min_eigenvalue_ratio = 0.0;  ///< smallest / largest of those eigenvalues
  double search_s = 0.0;              ///< time spent finding correspondences
  double optimize_s = 0.0;            ///< time spent building blocks and solving
};

/// Aligns `source` to `target` starting at T_target_source_init. Both clouds need covariances
/// (estimate_covariances); `target_tree` indexes target. Throws carat::Error if covariances are
/// missing or fewer than settings.min_correspondences pairs are found.
AlignResult align(const PointCloud& target, const KdTree& target_tree, const PointCloud& source,
                  const Eigen::Isometry3d& T_target_source_init,
                  const AlignSettings& settings = {});

}  // namespace carat
