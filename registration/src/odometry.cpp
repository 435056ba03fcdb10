#include "carat/registration/odometry.hpp"

#include <string>

#include "carat/base/error.hpp"

namespace carat {

OdometryResult run_odometry(std::span<const std::shared_ptr<const Frame>> frames,
                            std::span<const Eigen::Isometry3d> T_world_guess,
                            const AlignSettings& settings, int num_threads,
                            const std::function<void(std::size_t, std::size_t)>& progress) {
  if (frames.size() < 2)
    throw Error("odometry: at least 2 frames are needed, got " + std::to_string(frames.size()));
  if (frames.size() != T_world_guess.size()) {
    throw Error("odometry: " + std::to_string(frames.size()) + " frames but " +
                std::to_string(T_world_guess.size()) + " poses");
  }
  std::vector<FramePair> pairs;
  for (int i = 0; i + 1 < static_cast<int>(frames.size()); ++i) pairs.push_back({i, i + 1, 0.0});
  OdometryResult out;
  out.steps = register_pairs(frames, pairs, T_world_guess, settings, num_threads, progress);
  out.T_world_frame.reserve(frames.size());
  out.T_world_frame.push_back(T_world_guess[0]);
  for (const PairRegistration& step : out.steps)
    out.T_world_frame.push_back(out.T_world_frame.back() * step.T_target_source);
  return out;
}

}  // namespace carat
