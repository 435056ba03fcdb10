#pragma once

/// A drift model that turns ground-truth poses into a realistic initial guess.

#include <Eigen/Geometry>
#include <cstdint>
#include <span>
#include <vector>

namespace carat {

/// Drift model for an initial guess: settings.
struct DriftOptions {
  std::uint64_t seed = 1;           ///< seed of the perturbations
  double translation_sigma = 0.01;  ///< metres per metre travelled, std-dev per axis (>= 0)
  double rotation_sigma_deg = 0.1;  ///< degrees per metre travelled, std-dev per axis (>= 0)
  double heading_bias_deg = 0.0;    ///< degrees per metre travelled turned about each frame's z
                                    ///< axis on top (a systematic heading drift, e.g. 0.05 for
                                    ///< 5 degrees per 100 m); finite
};

/// Initial guess with realistic drift: starts at T_world_frame[0] and composes the ground-truth
/// relative motions, each right-multiplied by Exp([omega, v]) with omega and v Gaussian of
/// std-dev sigma times the distance of that motion (rotation first, as in carat::se3), and turned
/// by heading_bias_deg times that distance about z. Zero sigmas and bias return the input
/// unchanged. Deterministic in the seed. Throws carat::Error for a
/// negative or non-finite sigma.
std::vector<Eigen::Isometry3d> apply_drift(std::span<const Eigen::Isometry3d> T_world_frame,
                                           const DriftOptions& options);

}  // namespace carat
