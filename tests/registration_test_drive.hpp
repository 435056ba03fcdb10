#pragma once

// The synthetic drive several registration tests start from: preprocessed frames and the drift
// model's guess, without odometry or a dense graph.

#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

#include "carat/sim/pipeline.hpp"

namespace carat::test {

/// `frames` frames over `laps` laps of the world of `world_seed`, preprocessed at 0.5 m voxels
/// on 2 threads, with the drifting guess of `drift` (T_world_drift); no odometry, no dense graph.
inline SyntheticPipeline simulate_test_drive(std::uint64_t world_seed, int frames, int laps,
                                             const DriftOptions& drift) {
  SyntheticPipelineOptions options;
  options.world.seed = world_seed;
  options.drive.frames = frames;
  options.drive.laps = laps;
  options.preprocess.voxel_size = 0.5;
  options.drift = drift;
  options.odometry = false;
  options.dense_graph = false;
  options.threads = 2;
  return simulate_pipeline(options);
}

/// The frames of a test drive and its drifting guess.
struct DriftingDrive {
  std::vector<std::shared_ptr<const Frame>> frames;  ///< preprocessed, 0.5 m voxels
  std::vector<Eigen::Isometry3d> initial;            ///< T_world_drift
};

/// simulate_test_drive()'s frames and drifting guess.
inline DriftingDrive drifting_drive(std::uint64_t world_seed, int frames, int laps,
                                    const DriftOptions& drift) {
  SyntheticPipeline pipeline = simulate_test_drive(world_seed, frames, laps, drift);
  return {std::move(pipeline.frames), std::move(pipeline.T_world_drift)};
}

}  // namespace carat::test
