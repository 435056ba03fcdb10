#include "carat/registration/pair_registration.hpp"

#include <tbb/info.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <string>

#include "carat/base/error.hpp"
#include "carat/base/stopwatch.hpp"
#include "parallel.hpp"

namespace carat {

std::string PairRegistration::problem() const {
  if (!converged) return "did not converge";
  if (constrained_dof < 6) {
    return "fixes only " + std::to_string(constrained_dof) +
           " of 6 degrees of freedom (a degenerate scene, e.g. a single plane)";
  }
  return {};
}

std::vector<PairRegistration> register_pairs(
    FrameStore& frames, std::span<const FramePair> pairs,
    std::span<const Eigen::Isometry3d> T_world_frame, const AlignSettings& settings,
    int num_threads, const std::function<void(std::size_t, std::size_t)>& progress) {
  if (frames.size() != T_world_frame.size()) {
    throw Error("register_pairs: " + std::to_string(frames.size()) + " frames but " +
                std::to_string(T_world_frame.size()) + " poses");
  }
  const int n = static_cast<int>(frames.size());
  for (const FramePair& pair : pairs) {
    if (pair.target < 0 || pair.target >= n || pair.source < 0 || pair.source >= n ||
        pair.target == pair.source) {
      throw Error("register_pairs: pair (" + std::to_string(pair.target) + ", " +
                  std::to_string(pair.source) + ") does not name two distinct frames of " +
                  std::to_string(n));
    }
  }
  AlignSettings single = settings;
  single.num_threads = 1;
  std::vector<PairRegistration> out(pairs.size());
  const int threads = std::clamp(num_threads, 1, tbb::info::default_concurrency());
  tbb::task_arena arena(threads);
  std::atomic<std::size_t> done{0};
  const auto register_one = [&](std::size_t k) {
    const FramePair& pair = pairs[k];
    const std::shared_ptr<const Frame> target_frame =
        frames.get(static_cast<std::size_t>(pair.target));
    const std::shared_ptr<const Frame> source_frame =
        frames.get(static_cast<std::size_t>(pair.source));
    const Frame& target = *target_frame;
    const Frame& source = *source_frame;
    const Eigen::Isometry3d T_init =
        T_world_frame[static_cast<std::size_t>(pair.target)].inverse() *
        T_world_frame[static_cast<std::size_t>(pair.source)];
    AlignResult result;
    const Stopwatch align_time;
    try {
      result = align(target.cloud(), target.tree(), source.cloud(), T_init, single);
    } catch (const Error& e) {
      throw Error("aligning frame " + std::to_string(pair.source) + " to frame " +
                  std::to_string(pair.target) + ": " + e.what());
    }
    PairRegistration& r = out[k];
    r.pair = pair;
    r.T_target_source = result.T_target_source;
    r.H = result.H;
    r.error = result.error;
    r.num_correspondences = result.num_correspondences;
    r.iterations = result.iterations;
    r.converged = result.converged;
    r.constrained_dof = result.constrained_dof;
    r.align_s = align_time.elapsed_s();
    if (progress) progress(done.fetch_add(1) + 1, pairs.size());
  };
  arena.execute([&] {
    if (frames.resident()) {
      internal::parallel_for_each_index(pairs.size(), register_one);
    } else {
      internal::parallel_for_in_order(locality_order(pairs, T_world_frame), threads, register_one);
    }
  });
  return out;
}

}  // namespace carat
