#pragma once

/// A deterministic, seeded synthetic LiDAR world: a procedural city (sloped rough ground,
/// buildings with facade detail, poles, trees, parked cars, bushes), a simulated spinning
/// LiDAR that ray casts it, and a ground-truth circuit through its streets.
///
/// Layout: blocks_x x blocks_y square blocks of edge block_size, with streets of street_width
/// between them and around the grid, and a ring of buildings beyond the outer streets, so every
/// street has facades on both sides. Block (0, 0) covers [0, block_size]^2; the ground-truth
/// circuit follows the centre lines of the streets around block (0, 0) (or around a rectangle
/// of blocks from (0, 0)), counterclockwise with rounded corners. Objects near the ground stay
/// at least 3 m from every street centre line (tree canopies and street-light arms may
/// overhang the street above the sensor).
///
/// Randomness: every draw comes from std::mt19937_64 (its output is fixed by the C++ standard)
/// seeded through splitmix64, turned into uniforms and Gaussians (Box-Muller) by carat's own
/// code, so results do not depend on the standard library's distributions. Only the libm
/// functions (sin, cos, log, sqrt) could make results differ across platforms.

#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <vector>

#include "carat/registration/point_cloud.hpp"
#include "carat/sim/circuit_options.hpp"
#include "carat/sim/world_options.hpp"

namespace carat {

/// A procedural scene: ground with slope and roughness, buildings/walls (boxes), poles (vertical
/// cylinders), trees, parked cars and vegetation-like clutter, all derived from the seed.
/// Immutable once built; copies share the scene.
class SyntheticWorld {
 public:
  /// Builds the scene. Throws carat::Error naming the option for settings that make no sense.
  explicit SyntheticWorld(const SyntheticWorldOptions& options = {});

  /// One LiDAR sweep from sensor pose T_world_sensor, points in the SENSOR frame, channel by
  /// channel, azimuth 0..360 deg from +x towards +y; a ray that hits nothing gives no point.
  /// Ranges get Gaussian noise drawn from `noise_seed` (one draw per hit, in ray order); points
  /// whose noisy range falls outside [min_range, max_range] are dropped. Deterministic. Rays
  /// walk a 2-D grid of 4 m cells over the primitives (analytic box, cylinder and sphere
  /// intersections) and stop at the first hit or beyond max_range; the ground is hit exactly
  /// (first crossing of the height field, bracketed and refined by safeguarded Newton steps).
  PointCloud scan(const Eigen::Isometry3d& T_world_sensor, std::uint64_t noise_seed) const;

  /// The ground-truth circuit: T_world_sensor per frame (x forward, y left, z up along the
  /// ground plane's normal), sensor_height above the ground. Deterministic. Throws
  /// carat::Error naming the option for bad settings.
  std::vector<Eigen::Isometry3d> trajectory(const SyntheticTrajectoryOptions& options) const;

  /// Ground height z at (x, y): the tilted plane plus the smooth relief (metres, world frame).
  double ground_height(double x, double y) const;

  /// Unit normal of the tilted ground plane, relief excluded (world frame, pointing up).
  Eigen::Vector3d ground_normal() const;

  /// Distance along the unit direction `direction` from `origin` to the first surface (world
  /// frame), or a negative value when nothing is hit within `max_distance`. Noise free.
  double cast_ray(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                  double max_distance) const;

  /// Number of primitives (boxes, cylinders, spheres) in the scene, ground excluded.
  std::size_t num_primitives() const;

  /// The settings the world was built with.
  const SyntheticWorldOptions& options() const { return options_; }

 private:
  struct Scene;
  SyntheticWorldOptions options_;
  std::shared_ptr<const Scene> scene_;
};

}  // namespace carat
