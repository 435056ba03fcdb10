#pragma once

/// A deterministic, seeded synthetic LiDAR world: a procedural city (sloped rough ground,
/// buildings with facade detail, poles, trees, parked cars, bushes), a simulated spinning
/// LiDAR that ray casts it, a ground-truth circuit, a drift model for initial guesses, and a
/// KITTI-style writer for whole drives.
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
#include <filesystem>
#include <functional>
#include <memory>
#include <span>
#include <vector>

#include "carat/registration/point_cloud.hpp"

namespace carat {

/// Settings of the procedural scene and the simulated spinning LiDAR.
struct SyntheticWorldOptions {
  std::uint64_t seed = 1;  ///< the scene (and, through make_synthetic_sequence, the noise)
  // Scene.
  double block_size = 40.0;        ///< metres, edge of a square block (>= 10)
  double street_width = 14.0;      ///< metres (>= 8: a 6 m lane kept clear plus sidewalks)
  int blocks_x = 2;                ///< blocks along x (>= 1)
  int blocks_y = 2;                ///< blocks along y (>= 1)
  double ground_slope = 0.01;      ///< rad, tilt of the ground plane (|slope| <= 0.2)
  double ground_roughness = 0.03;  ///< metres, amplitude of a smooth sum-of-sines relief (>= 0)
  // Sensor.
  int beams = 32;                    ///< vertical channels, evenly spaced in elevation (>= 1)
  double min_elevation_deg = -25.0;  ///< lowest channel, degrees (> -90)
  double max_elevation_deg = 10.0;   ///< highest channel, degrees (< 90, >= min)
  int azimuth_steps = 1024;          ///< rays per channel per revolution (>= 8)
  double min_range = 1.0;            ///< metres; shorter measured ranges are dropped (> 0)
  double max_range = 60.0;           ///< metres; longer measured ranges are dropped (> min)
  double range_noise = 0.02;         ///< metres, std-dev of Gaussian range noise (>= 0)
  double sensor_height = 1.8;        ///< metres above the ground (in (0, 2.5])
};

/// Ground-truth circuit settings: the streets around the blocks [0, circuit_blocks_x) x
/// [0, circuit_blocks_y) (by default block (0, 0) alone), driven `laps` times.
/// Frames are evenly spaced in lap fraction, so frame k and frame k + frames / laps sit at the
/// same place of their laps (when laps divides frames). Lap l drives lap_offset * {0, +1, -1}
/// [l % 3] metres outward of the centre line and turns the heading by lap_yaw_deg times the
/// same factor, so repeated laps do not give identical scans. The defaults give a circuit of
/// about 199 m, frames about 4 m apart, and about 23 deg of turn between frames in corners.
struct SyntheticTrajectoryOptions {
  int frames = 100;             ///< poses in all (>= 2)
  int laps = 2;                 ///< laps of the circuit (>= 1)
  double corner_radius = 10.0;  ///< metres, corner rounding (> lap_offset, < (block + street) / 2)
  double lap_offset = 0.7;      ///< metres, sideways offset of alternate laps (in [0, 1.5])
  double lap_yaw_deg = 2.0;     ///< degrees, heading offset of alternate laps (|.| <= 10)
  int circuit_blocks_x = 1;     ///< blocks the circuit goes around along x (<= the world's)
  int circuit_blocks_y = 1;     ///< blocks the circuit goes around along y (<= the world's)
};

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

  /// Ground height z at (x, y): the tilted plane plus the smooth relief.
  double ground_height(double x, double y) const;

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

/// Frames and ground truth of a simulated drive.
struct SyntheticSequence {
  std::vector<PointCloud> scans;                 ///< sensor frame, one per pose
  std::vector<Eigen::Isometry3d> T_world_frame;  ///< ground truth
};

/// Noise seed of frame `frame` in make_synthetic_sequence (splitmix64 of seed and frame).
std::uint64_t synthetic_frame_noise_seed(std::uint64_t seed, std::size_t frame);

/// Simulates a whole drive along world.trajectory(options): frame k is scanned with noise seed
/// synthetic_frame_noise_seed(world seed, k). Scans run in parallel with TBB; the result does
/// not depend on the number of threads.
SyntheticSequence make_synthetic_sequence(const SyntheticWorld& world,
                                          const SyntheticTrajectoryOptions& options);

/// Drift model for an initial guess: settings.
struct DriftOptions {
  std::uint64_t seed = 1;           ///< seed of the perturbations
  double translation_sigma = 0.01;  ///< metres per metre travelled, std-dev per axis (>= 0)
  double rotation_sigma_deg = 0.1;  ///< degrees per metre travelled, std-dev per axis (>= 0)
};

/// Initial guess with realistic drift: starts at T_world_frame[0] and composes the ground-truth
/// relative motions, each right-multiplied by Exp([omega, v]) with omega and v Gaussian of
/// std-dev sigma times the distance of that motion (rotation first, as in carat::se3). Zero
/// sigmas return the input unchanged. Deterministic in the seed. Throws carat::Error for a
/// negative or non-finite sigma.
std::vector<Eigen::Isometry3d> apply_drift(std::span<const Eigen::Isometry3d> T_world_frame,
                                           const DriftOptions& options);

/// Writes a sequence as KITTI lays it out: DIR/NNNNNN.bin (x y z intensity float32, intensity
/// 0, KittiFormat::kXyzi, what `carat map` reads by default) and
/// DIR/poses.txt (12 numbers per line, row-major 3x4 of T_world_frame, %.9g). Creates DIR;
/// every file is written atomically. Throws carat::Error when scans and poses differ in number
/// or a file cannot be written.
void write_synthetic_sequence(const std::filesystem::path& dir, const SyntheticSequence& sequence);

/// Simulates the drive along world.trajectory(options) and writes it into DIR frame by frame,
/// with the same files as make_synthetic_sequence() then write_synthetic_sequence(), holding
/// only one scan per running thread in memory (so a drive of any length fits). Scans run in
/// parallel with TBB. `progress`, if set, gets (frames written, frames). Returns the number of
/// points written. Throws carat::Error as trajectory() and write_synthetic_sequence() do.
std::size_t write_synthetic_drive(
    const std::filesystem::path& dir, const SyntheticWorld& world,
    const SyntheticTrajectoryOptions& options,
    const std::function<void(std::size_t, std::size_t)>& progress = {});

}  // namespace carat
