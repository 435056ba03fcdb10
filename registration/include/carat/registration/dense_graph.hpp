#pragma once

/// The dense registration graph: a factor for every pair of frames whose scans overlap enough
/// under the current poses, plus every consecutive pair.

#include <Eigen/Geometry>
#include <functional>
#include <memory>
#include <span>
#include <vector>

#include "carat/registration/frame.hpp"
#include "carat/registration/frame_store.hpp"

namespace carat {

/// Settings of build_dense_graph().
struct DenseGraphOptions {
  double overlap_threshold = 0.2;  ///< pairs with at least this overlap fraction get a factor
  double voxel_size = 1.0;         ///< voxel edge of the overlap test, metres
  double max_distance = 100.0;     ///< pairs whose sensors are farther apart are not tested (m)
  int overlap_stride = 4;          ///< test every this-many-th source point (speed)
  int num_threads = 1;             ///< threads for the overlap tests
};

/// One factor of the graph: frame `target` (i) and frame `source` (j), i < j.
struct FramePair {
  int target = 0;        ///< index i of the target frame
  int source = 0;        ///< index j of the source frame
  double overlap = 0.0;  ///< overlap fraction of source in target at the poses used
};

/// Every consecutive pair (i, i+1) and every other pair i < j with overlap >= threshold under
/// T_world_frame, sorted by (target, source). Throws carat::Error when frames and poses differ
/// in count, fewer than 2 frames are given, a pose is not finite, or an option is out of range.
/// `progress`, if set, is called with (pairs tested, pairs to test) from any thread.
/// Each frame is requested once, in index order, and only what the overlap tests need of it is
/// kept (its occupied voxels and every overlap_stride-th point, a few percent of a frame), so a
/// store that reads frames on demand stays small.
std::vector<FramePair> build_dense_graph(
    FrameStore& frames, std::span<const Eigen::Isometry3d> T_world_frame,
    const DenseGraphOptions& options = {},
    const std::function<void(std::size_t, std::size_t)>& progress = {});

/// The pairs build_dense_graph() tests, in its order: every consecutive pair (i, i+1), then every
/// pair i + 2 <= j whose sensors lie within options.max_distance (overlap 0, not yet measured).
/// Throws carat::Error as build_dense_graph() does for the poses and options (no frames needed).
std::vector<FramePair> dense_graph_candidates(std::span<const Eigen::Isometry3d> T_world_frame,
                                              const DenseGraphOptions& options = {});

/// Measures the overlap fraction of each of `pairs` under T_world_frame into its `overlap`, as
/// build_dense_graph() does (so a share of the candidates measured anywhere gives the same
/// numbers). Only the frames the pairs name are requested, each once.
/// Throws carat::Error when frames and poses differ in count, a pair names a frame out of range,
/// or an option is out of range; `progress` as build_dense_graph()'s (pairs measured, pairs).
void measure_overlaps(FrameStore& frames, std::span<const Eigen::Isometry3d> T_world_frame,
                      std::span<FramePair> pairs, const DenseGraphOptions& options = {},
                      const std::function<void(std::size_t, std::size_t)>& progress = {});

/// The graph from measured candidates (dense_graph_candidates() with measure_overlaps() applied):
/// every consecutive pair and every other pair at or above options.overlap_threshold, sorted by
/// (target, source).
std::vector<FramePair> select_dense_graph(std::span<const FramePair> measured,
                                          const DenseGraphOptions& options = {});

/// Deprecated: the same from frames in memory.
[[deprecated("wrap the frames in a carat::FrameStore")]] inline std::vector<FramePair>
build_dense_graph(std::span<const std::shared_ptr<const Frame>> frames,
                  std::span<const Eigen::Isometry3d> T_world_frame,
                  const DenseGraphOptions& options = {},
                  const std::function<void(std::size_t, std::size_t)>& progress = {}) {
  FrameStore store = resident_store(frames);
  return build_dense_graph(store, T_world_frame, options, progress);
}

/// A processing order of `pairs` (a permutation of their indices) under which a bounded cache
/// of frames meets each frame in few separate stretches: pairs sorted by the Morton code of the
/// cell (cell_size metres) that holds the midpoint of their two frames' positions, then by
/// target and source. Throws carat::Error for a pair naming a frame without a pose, a
/// non-finite pose or cell_size <= 0.
std::vector<std::size_t> locality_order(std::span<const FramePair> pairs,
                                        std::span<const Eigen::Isometry3d> T_world_frame,
                                        double cell_size = 10.0);

}  // namespace carat
