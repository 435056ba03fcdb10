#pragma once

/// A scan prepared for registration: voxel-downsampled points with GICP covariances and a k-d
/// tree over them, held together so the tree never outlives or loses its cloud.

#include <cstddef>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "carat/registration/covariance.hpp"
#include "carat/registration/kdtree.hpp"
#include "carat/registration/point_cloud.hpp"

namespace carat {

/// Settings of preprocess_frame().
struct PreprocessOptions {
  double voxel_size = 0.5;        ///< downsampling voxel edge, metres (> 0)
  int covariance_neighbors = 10;  ///< k of the covariance estimate (>= 4)
  int min_points = 29;            ///< fewer points after downsampling is an error
  int num_threads = 1;            ///< threads for the voxel grid and the covariance estimate
};

/// A downsampled cloud with covariances and its k-d tree (immutable once built).
class Frame {
 public:
  /// Takes a cloud that already has covariances and builds its tree. Throws carat::Error if
  /// the cloud has no covariances.
  explicit Frame(PointCloud cloud);
  /// Takes a cloud, builds its tree and estimates the covariances with that tree (replacing any
  /// the cloud had). Throws carat::Error as estimate_covariances() does.
  Frame(PointCloud cloud, const CovarianceOptions& covariance);
  Frame(const Frame&) = delete;
  Frame& operator=(const Frame&) = delete;

  /// The points (frame's own coordinates) and their covariances.
  const PointCloud& cloud() const { return *cloud_; }
  /// The k-d tree over cloud().
  const KdTree& tree() const { return *tree_; }
  /// Number of points.
  std::size_t size() const { return cloud_->size(); }
  /// Bytes the frame holds: its points, covariances and k-d tree.
  std::size_t memory_bytes() const;
  /// The name given to preprocess_frame() (a file, "synthetic frame 3"), for messages; may be
  /// empty.
  const std::string& name() const { return name_; }
  /// Sets the name used in messages.
  void set_name(std::string name) { name_ = std::move(name); }
  /// Directions of the frame's pose (of 6) that its own geometry fixes for registration: the
  /// eigenvalues of sum_k J_k^T C_k^-1 J_k over its points (J = d(T p_k)/d xi at identity,
  /// rotations scaled by the RMS point radius so all six are in metres) above 5e-3 of the
  /// largest, the test `carat align` applies to a pair. A plane fixes 3, a line at most 4.
  int constrained_dof() const { return constrained_dof_; }
  /// Smallest / largest of those eigenvalues (0 for a degenerate frame).
  double min_eigenvalue_ratio() const { return min_eigenvalue_ratio_; }

 private:
  void measure_constraint();

  std::unique_ptr<PointCloud> cloud_;  // on the heap: the tree keeps a reference to it
  std::unique_ptr<KdTree> tree_;
  std::string name_;
  int constrained_dof_ = 0;
  double min_eigenvalue_ratio_ = 0.0;
};

/// The points preprocess_frame() keeps of `raw` (downsampled, frame coordinates), without
/// covariances or tree: what an overlap test needs, at a small part of the cost. Throws
/// carat::Error as preprocess_frame() does, with the same messages.
PointCloud downsample_frame_points(const PointCloud& raw, const PreprocessOptions& options,
                                   const std::string& name);

/// Downsamples `raw`, estimates covariances and builds the tree. `name` (a file name or
/// "frame 12") is used in errors and kept as the frame's name(); throws carat::Error for bad
/// options or a frame with fewer than min_points points after downsampling.
std::shared_ptr<const Frame> preprocess_frame(const PointCloud& raw,
                                              const PreprocessOptions& options,
                                              const std::string& name);

/// Preprocesses `count` scans in parallel with `num_threads` threads: load(k) returns scan k
/// (called once per scan, from any thread; read a file there to keep only a few raw scans in
/// memory) and name(k) names it in errors. `progress`, if set, gets (scans done, count).
/// Results are in scan order and do not depend on the thread count.
std::vector<std::shared_ptr<const Frame>> preprocess_frames(
    std::size_t count, const std::function<PointCloud(std::size_t)>& load,
    const std::function<std::string(std::size_t)>& name, const PreprocessOptions& options,
    int num_threads, const std::function<void(std::size_t, std::size_t)>& progress = {});

}  // namespace carat
