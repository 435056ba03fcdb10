#pragma once

/// Settings of the ground-truth circuit driven through the synthetic world.

namespace carat {

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

}  // namespace carat
