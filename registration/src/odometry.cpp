#include "carat/registration/odometry.hpp"

#include <string>

#include "carat/base/error.hpp"

namespace carat {

std::size_t OdometryResult::unreliable_steps() const {
  std::size_t count = 0;
  for (const PairRegistration& step : steps) count += step.reliable() ? 0 : 1;
  return count;
}

std::string OdometryResult::describe_unreliable_steps(FrameStore& frames, std::size_t limit) const {
  const auto name = [&](int k) {
    const auto i = static_cast<std::size_t>(k);
    if (i >= frames.size()) return std::to_string(k);
    const std::string frame_name = frames.get(i)->name();
    return frame_name.empty() ? std::to_string(k) : frame_name;
  };
  std::string text;
  std::size_t listed = 0;
  for (const PairRegistration& step : steps) {
    if (step.reliable()) continue;
    if (listed++ == limit) continue;
    if (!text.empty()) text += "; ";
    text += name(step.pair.target) + " -> " + name(step.pair.source) + " " + step.problem();
  }
  if (listed > limit) text += "; and " + std::to_string(listed - limit) + " more";
  return text;
}

OdometryResult run_odometry(FrameStore& frames, std::span<const Eigen::Isometry3d> T_world_guess,
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

OdometryResult run_scan_odometry(FrameStore& frames, const AlignSettings& settings,
                                 const std::function<void(std::size_t, std::size_t)>& progress) {
  if (frames.size() < 2)
    throw Error("odometry: at least 2 frames are needed, got " + std::to_string(frames.size()));
  OdometryResult out;
  out.T_world_frame.push_back(Eigen::Isometry3d::Identity());
  Eigen::Isometry3d motion = Eigen::Isometry3d::Identity();
  for (std::size_t k = 0; k + 1 < frames.size(); ++k) {
    const std::shared_ptr<const Frame> target_frame = frames.get(k);
    const std::shared_ptr<const Frame> source_frame = frames.get(k + 1);
    const Frame& target = *target_frame;
    const Frame& source = *source_frame;
    AlignSettings coarse = settings;
    coarse.max_correspondence_distance = 3.0 * settings.max_correspondence_distance;
    AlignResult result;
    try {
      const AlignResult first =
          align(target.cloud(), target.tree(), source.cloud(), motion, coarse);
      result =
          align(target.cloud(), target.tree(), source.cloud(), first.T_target_source, settings);
    } catch (const Error& e) {
      throw Error("aligning " + source.name() + " to " + target.name() + ": " + e.what());
    }
    PairRegistration step;
    step.pair = FramePair{static_cast<int>(k), static_cast<int>(k + 1), 0.0};
    step.T_target_source = result.T_target_source;
    step.H = result.H;
    step.error = result.error;
    step.num_correspondences = result.num_correspondences;
    step.iterations = result.iterations;
    step.converged = result.converged;
    step.constrained_dof = result.constrained_dof;
    out.steps.push_back(step);
    out.T_world_frame.push_back(out.T_world_frame.back() * result.T_target_source);
    motion = result.T_target_source;
    if (progress) progress(k + 1, frames.size() - 1);
  }
  return out;
}

}  // namespace carat
