#include "carat/registration/dense_graph.hpp"

#include <tbb/blocked_range.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <string>

#include "carat/base/error.hpp"
#include "carat/registration/overlap.hpp"
#include "parallel.hpp"

namespace carat {

std::vector<FramePair> build_dense_graph(
    std::span<const std::shared_ptr<const Frame>> frames,
    std::span<const Eigen::Isometry3d> T_world_frame, const DenseGraphOptions& options,
    const std::function<void(std::size_t, std::size_t)>& progress) {
  if (frames.size() != T_world_frame.size()) {
    throw Error("build_dense_graph: " + std::to_string(frames.size()) + " frames but " +
                std::to_string(T_world_frame.size()) + " poses");
  }
  if (frames.size() < 2)
    throw Error("the dense graph needs at least 2 frames, got " + std::to_string(frames.size()));
  if (!(options.overlap_threshold >= 0.0 && options.overlap_threshold <= 1.0))
    throw Error("build_dense_graph: overlap_threshold must be in [0, 1]");
  if (!(options.max_distance > 0.0)) throw Error("build_dense_graph: max_distance must be > 0");
  if (options.overlap_stride < 1) throw Error("build_dense_graph: overlap_stride must be >= 1");
  for (std::size_t i = 0; i < frames.size(); ++i) {
    if (!frames[i]) throw Error("build_dense_graph: frame " + std::to_string(i) + " is null");
    if (!T_world_frame[i].matrix().allFinite())
      throw Error("build_dense_graph: pose " + std::to_string(i) + " is not finite");
  }
  const int n = static_cast<int>(frames.size());
  // Candidates: non-consecutive pairs whose sensors are close enough.
  std::vector<FramePair> candidates;
  for (int i = 0; i < n; ++i) {
    for (int j = i + 2; j < n; ++j) {
      const double distance =
          (T_world_frame[i].translation() - T_world_frame[j].translation()).norm();
      if (distance <= options.max_distance) candidates.push_back({i, j, 0.0});
    }
  }
  std::vector<FramePair> consecutive;
  for (int i = 0; i + 1 < n; ++i) consecutive.push_back({i, i + 1, 0.0});

  const int threads = std::clamp(options.num_threads, 1, tbb::info::default_concurrency());
  tbb::task_arena arena(threads);
  std::vector<std::unique_ptr<VoxelOccupancy>> occupancy(frames.size());
  std::atomic<std::size_t> done{0};
  const std::size_t total = candidates.size() + consecutive.size();
  arena.execute([&] {
    internal::parallel_for_each_index(frames.size(), [&](std::size_t i) {
      occupancy[i] = std::make_unique<VoxelOccupancy>(frames[i]->cloud(), options.voxel_size);
    });
    const auto measure = [&](std::vector<FramePair>& pairs) {
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, pairs.size(), 16), [&](const auto& r) {
        for (std::size_t k = r.begin(); k != r.end(); ++k) {
          FramePair& pair = pairs[k];
          const auto i = static_cast<std::size_t>(pair.target);
          const auto j = static_cast<std::size_t>(pair.source);
          pair.overlap = overlap_fraction(*occupancy[i], frames[j]->cloud(),
                                          T_world_frame[i].inverse() * T_world_frame[j],
                                          options.overlap_stride);
        }
        const std::size_t now = done.fetch_add(r.size()) + r.size();
        if (progress) progress(now, total);
      });
    };
    measure(consecutive);
    measure(candidates);
  });
  std::vector<FramePair> graph = consecutive;
  for (const FramePair& pair : candidates)
    if (pair.overlap >= options.overlap_threshold) graph.push_back(pair);
  std::sort(graph.begin(), graph.end(), [](const FramePair& a, const FramePair& b) {
    return a.target != b.target ? a.target < b.target : a.source < b.source;
  });
  return graph;
}

}  // namespace carat
