#pragma once

/// Settings of the synthetic world: the procedural city and the simulated spinning LiDAR.

#include <cstdint>

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

}  // namespace carat
