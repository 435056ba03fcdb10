#pragma once

/// Seeded pose perturbations, for starting an optimization away from known poses.

#include <Eigen/Geometry>
#include <cstdint>
#include <span>
#include <vector>

namespace carat {

/// Returns the poses with poses[k] * D for k >= first, where D rotates by |w| = degrees (in
/// radians) about w and then translates by v with |v| = metres, exactly, in directions drawn
/// uniformly on the sphere from `seed` (std::mt19937_64). Throws carat::Error for negative or
/// non-finite magnitudes.
std::vector<Eigen::Isometry3d> perturb_poses(std::span<const Eigen::Isometry3d> poses,
                                             double metres, double degrees, std::uint64_t seed,
                                             std::size_t first = 1);

}  // namespace carat
