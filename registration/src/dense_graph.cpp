#include "carat/registration/dense_graph.hpp"

#include <tbb/blocked_range.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <string>

#include "carat/base/error.hpp"
#include "carat/registration/overlap.hpp"
#include "parallel.hpp"

namespace carat {

namespace {

void check_graph_options(const DenseGraphOptions& options) {
  if (!(options.overlap_threshold >= 0.0 && options.overlap_threshold <= 1.0))
    throw Error("build_dense_graph: overlap_threshold must be in [0, 1]");
  if (!(options.max_distance > 0.0)) throw Error("build_dense_graph: max_distance must be > 0");
  if (options.overlap_stride < 1) throw Error("build_dense_graph: overlap_stride must be >= 1");
}

}  // namespace

std::vector<FramePair> dense_graph_candidates(std::span<const Eigen::Isometry3d> T_world_frame,
                                              const DenseGraphOptions& options) {
  if (T_world_frame.size() < 2) {
    throw Error("the dense graph needs at least 2 frames, got " +
                std::to_string(T_world_frame.size()));
  }
  check_graph_options(options);
  for (std::size_t i = 0; i < T_world_frame.size(); ++i) {
    if (!T_world_frame[i].matrix().allFinite())
      throw Error("build_dense_graph: pose " + std::to_string(i) + " is not finite");
  }
  const int n = static_cast<int>(T_world_frame.size());
  std::vector<FramePair> out;
  for (int i = 0; i + 1 < n; ++i) out.push_back({i, i + 1, 0.0});
  // Non-consecutive pairs whose sensors are close enough.
  for (int i = 0; i < n; ++i) {
    for (int j = i + 2; j < n; ++j) {
      const double distance =
          (T_world_frame[i].translation() - T_world_frame[j].translation()).norm();
      if (distance <= options.max_distance) out.push_back({i, j, 0.0});
    }
  }
  return out;
}

void measure_overlaps(FrameStore& frames, std::span<const Eigen::Isometry3d> T_world_frame,
                      std::span<FramePair> pairs, const DenseGraphOptions& options,
                      const std::function<void(std::size_t, std::size_t)>& progress) {
  if (frames.size() != T_world_frame.size()) {
    throw Error("build_dense_graph: " + std::to_string(frames.size()) + " frames but " +
                std::to_string(T_world_frame.size()) + " poses");
  }
  check_graph_options(options);
  const int n = static_cast<int>(frames.size());
  std::vector<char> needed(frames.size(), 0);
  for (const FramePair& pair : pairs) {
    if (pair.target < 0 || pair.target >= n || pair.source < 0 || pair.source >= n) {
      throw Error("build_dense_graph: pair (" + std::to_string(pair.target) + ", " +
                  std::to_string(pair.source) + ") names a frame out of range (" +
                  std::to_string(n) + " frames)");
    }
    needed[static_cast<std::size_t>(pair.target)] = 1;
    needed[static_cast<std::size_t>(pair.source)] = 1;
  }
  std::vector<std::size_t> wanted;
  for (std::size_t i = 0; i < needed.size(); ++i)
    if (needed[i]) wanted.push_back(i);

  const int threads = std::clamp(options.num_threads, 1, tbb::info::default_concurrency());
  tbb::task_arena arena(threads);
  // Per frame, what the tests need: its occupied voxels (as target) and every stride-th point
  // (as source; the same points overlap_fraction() visits with that stride).
  std::vector<std::unique_ptr<VoxelOccupancy>> occupancy(frames.size());
  std::vector<PointCloud> sampled(frames.size());
  std::atomic<std::size_t> done{0};
  const std::size_t total = pairs.size();
  const auto stride = static_cast<std::size_t>(options.overlap_stride);
  arena.execute([&] {
    internal::parallel_for_each_index(wanted.size(), [&](std::size_t w) {
      const std::size_t i = wanted[w];
      // Points alone: a store that can read them without the covariances and tree does so.
      const std::shared_ptr<const PointCloud> cloud = frames.points(i);
      occupancy[i] = std::make_unique<VoxelOccupancy>(*cloud, options.voxel_size);
      const auto& points = cloud->points;
      sampled[i].points.reserve((points.size() + stride - 1) / stride);
      for (std::size_t k = 0; k < points.size(); k += stride)
        sampled[i].points.push_back(points[k]);
    });
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, pairs.size(), 16), [&](const auto& r) {
      for (std::size_t k = r.begin(); k != r.end(); ++k) {
        FramePair& pair = pairs[k];
        const auto i = static_cast<std::size_t>(pair.target);
        const auto j = static_cast<std::size_t>(pair.source);
        pair.overlap = overlap_fraction(*occupancy[i], sampled[j],
                                        T_world_frame[i].inverse() * T_world_frame[j], 1);
      }
      const std::size_t now = done.fetch_add(r.size()) + r.size();
      if (progress) progress(now, total);
    });
  });
}

std::vector<FramePair> select_dense_graph(std::span<const FramePair> measured,
                                          const DenseGraphOptions& options) {
  std::vector<FramePair> graph;
  for (const FramePair& pair : measured) {
    if (pair.source == pair.target + 1 || pair.overlap >= options.overlap_threshold)
      graph.push_back(pair);
  }
  std::sort(graph.begin(), graph.end(), [](const FramePair& a, const FramePair& b) {
    return a.target != b.target ? a.target < b.target : a.source < b.source;
  });
  return graph;
}

std::vector<FramePair> build_dense_graph(
    FrameStore& frames, std::span<const Eigen::Isometry3d> T_world_frame,
    const DenseGraphOptions& options,
    const std::function<void(std::size_t, std::size_t)>& progress) {
  if (frames.size() != T_world_frame.size()) {
    throw Error("build_dense_graph: " + std::to_string(frames.size()) + " frames but " +
                std::to_string(T_world_frame.size()) + " poses");
  }
  std::vector<FramePair> candidates = dense_graph_candidates(T_world_frame, options);
  measure_overlaps(frames, T_world_frame, candidates, options, progress);
  return select_dense_graph(candidates, options);
}

namespace {

/// Spreads the low 21 bits of v to every third bit.
std::uint64_t spread_bits(std::uint64_t v) {
  v &= 0x1fffff;
  v = (v | v << 32) & 0x1f00000000ffffULL;
  v = (v | v << 16) & 0x1f0000ff0000ffULL;
  v = (v | v << 8) & 0x100f00f00f00f00fULL;
  v = (v | v << 4) & 0x10c30c30c30c30c3ULL;
  v = (v | v << 2) & 0x1249249249249249ULL;
  return v;
}

}  // namespace

std::vector<std::size_t> locality_order(std::span<const FramePair> pairs,
                                        std::span<const Eigen::Isometry3d> T_world_frame,
                                        double cell_size) {
  if (!(cell_size > 0.0) || !std::isfinite(cell_size))
    throw Error("locality_order: cell_size must be finite and > 0");
  Eigen::Vector3d low = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  for (std::size_t i = 0; i < T_world_frame.size(); ++i) {
    if (!T_world_frame[i].translation().allFinite())
      throw Error("locality_order: pose " + std::to_string(i) + " is not finite");
    low = low.cwiseMin(T_world_frame[i].translation());
  }
  const int n = static_cast<int>(T_world_frame.size());
  std::vector<std::uint64_t> keys(pairs.size());
  for (std::size_t k = 0; k < pairs.size(); ++k) {
    const FramePair& pair = pairs[k];
    if (pair.target < 0 || pair.target >= n || pair.source < 0 || pair.source >= n) {
      throw Error("locality_order: pair (" + std::to_string(pair.target) + ", " +
                  std::to_string(pair.source) + ") names a frame without a pose");
    }
    const Eigen::Vector3d middle =
        0.5 * (T_world_frame[static_cast<std::size_t>(pair.target)].translation() +
               T_world_frame[static_cast<std::size_t>(pair.source)].translation());
    std::uint64_t key = 0;
    for (int axis = 0; axis < 3; ++axis) {
      const double cell = std::min(std::floor((middle[axis] - low[axis]) / cell_size), 2097151.0);
      key |= spread_bits(static_cast<std::uint64_t>(std::max(cell, 0.0))) << axis;
    }
    keys[k] = key;
  }
  std::vector<std::size_t> order(pairs.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    if (keys[a] != keys[b]) return keys[a] < keys[b];
    if (pairs[a].target != pairs[b].target) return pairs[a].target < pairs[b].target;
    return pairs[a].source < pairs[b].source;
  });
  return order;
}

}  // namespace carat
