#pragma once

/// A simulated drive: every frame of the circuit scanned, with its ground-truth pose.

#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "carat/registration/point_cloud.hpp"
#include "carat/sim/circuit_options.hpp"
#include "carat/sim/world.hpp"

namespace carat {

/// Frames and ground truth of a simulated drive.
struct SyntheticSequence {
  std::vector<PointCloud> scans;                 ///< sensor frame, one per pose
  std::vector<Eigen::Isometry3d> T_world_frame;  ///< ground truth
};

/// Noise seed of frame `frame` in make_synthetic_sequence (splitmix64 of seed and frame).
std::uint64_t synthetic_frame_noise_seed(std::uint64_t seed, std::size_t frame);

/// The first scan of the drive along world.trajectory(options), as make_synthetic_sequence() makes
/// it: every scan of a drive is about as large, so it prices a drive (disk, memory) before the
/// drive is simulated.
PointCloud first_scan(const SyntheticWorld& world, const SyntheticTrajectoryOptions& options);

/// Simulates a whole drive along world.trajectory(options): frame k is scanned with noise seed
/// synthetic_frame_noise_seed(world seed, k). Scans run in parallel with TBB; the result does
/// not depend on the number of threads.
SyntheticSequence make_synthetic_sequence(const SyntheticWorld& world,
                                          const SyntheticTrajectoryOptions& options);

}  // namespace carat
