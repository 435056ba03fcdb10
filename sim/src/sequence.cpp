#include "carat/sim/sequence.hpp"

#include <tbb/parallel_for.h>

#include "random.hpp"

namespace carat {

std::uint64_t synthetic_frame_noise_seed(std::uint64_t seed, std::size_t frame) {
  return sim_detail::splitmix64(seed ^ sim_detail::splitmix64(0x5eed0000ULL + frame));
}

PointCloud first_scan(const SyntheticWorld& world, const SyntheticTrajectoryOptions& options) {
  const Eigen::Isometry3d T_world_first = world.trajectory(options).front();
  return world.scan(T_world_first, synthetic_frame_noise_seed(world.options().seed, 0));
}

SyntheticSequence make_synthetic_sequence(const SyntheticWorld& world,
                                          const SyntheticTrajectoryOptions& options) {
  SyntheticSequence sequence;
  sequence.T_world_frame = world.trajectory(options);
  sequence.scans.resize(sequence.T_world_frame.size());
  tbb::parallel_for(std::size_t{0}, sequence.scans.size(), [&](std::size_t k) {
    sequence.scans[k] =
        world.scan(sequence.T_world_frame[k], synthetic_frame_noise_seed(world.options().seed, k));
  });
  return sequence;
}

}  // namespace carat
