#pragma once

/// A seeded synthetic bundle-adjustment scene in the BAL camera model (snavely_camera.hpp): true
/// cameras and points in a chosen layout, every point observed by a fixed number of cameras that
/// all have it in front of them, observations with Gaussian pixel noise and optional outliers, and
/// a start perturbed from the truth. Scene units are metres; image coordinates are pixels.

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "carat/residuals/bal_problem.hpp"

namespace carat {

/// Where the cameras stand and what they look at.
enum class BalLayout {
  kRing,    ///< on a circle of radius 10 m around the scene, looking inward at a central cylinder
  kStreet,  ///< along a straight street 1 m apart, looking sideways at a facade 8-10 m away
  kRandom,  ///< at random directions 8-12 m from the centre, looking at a central ball
};

/// "ring", "street" or "random".
const char* to_string(BalLayout layout);

/// The layout named "ring", "street" or "random"; throws carat::Error naming the valid ones.
BalLayout parse_bal_layout(std::string_view name);

/// Size, noise and start of a synthetic BAL scene.
struct BalSimulationOptions {
  BalLayout layout = BalLayout::kRing;      ///< camera layout
  int cameras = 16;                         ///< cameras (>= 2)
  int points = 1000;                        ///< points (>= cameras, so each camera observes one)
  int observations_per_point = 4;           ///< cameras observing each point, in [2, cameras]
  double pixel_noise_sigma = 1.0;           ///< Gaussian noise per image coordinate, pixels (>= 0)
  double outlier_fraction = 0.0;            ///< share of observations made outliers, in [0, 1]
  double outlier_pixels = 100.0;            ///< outliers move 1/2 to 1 times this far, pixels (> 0)
  double focal_px = 500.0;                  ///< mean focal length, pixels (> 0)
  double camera_rotation_sigma_rad = 0.01;  ///< start: rotation noise per axis, radians (>= 0)
  double camera_position_sigma_m = 0.1;     ///< start: camera centre noise per axis, metres
  double focal_sigma_relative = 0.01;       ///< start: focal length noise, relative (>= 0)
  double point_sigma_m = 0.1;               ///< start: point noise per axis, metres (>= 0)
  std::uint64_t seed = 1;                   ///< random seed (same seed, same scene on any platform)
};

/// The scene: the truth and the problem to solve, with the same cameras, points and
/// observation order.
struct BalScene {
  BalProblem truth;           ///< true cameras and points, noise-free observations
  BalProblem problem;         ///< perturbed cameras and points, noisy observations with outliers
  std::vector<char> outlier;  ///< 1 where problem.observations[k] is an outlier
};

/// The most observations per point `layout` can place with `cameras` cameras: every camera for
/// the ring and random layouts (all look at the central points); for the street, the cameras
/// that can all have a facade point at least 1 m in front of them (57 consecutive cameras: a
/// point further along the street can fall behind one that looks slightly the other way), or
/// `cameras` if fewer.
int max_observations_per_point(BalLayout layout, int cameras);

/// Generates the scene: exactly `cameras` cameras, `points` points and points *
/// observations_per_point observations (grouped by point), every camera observing at least one
/// point and every observed point in front of its camera (P_z < 0). Exactly
/// round(outlier_fraction * observations) observations are outliers. Random numbers come from
/// std::mt19937_64 through carat's own uniform and Gaussian transforms, so a seed gives the same
/// scene everywhere. Throws carat::Error for out-of-range options, among them more observations
/// per point than max_observations_per_point(), before any work.
BalScene simulate_bal(const BalSimulationOptions& options = {});

}  // namespace carat
