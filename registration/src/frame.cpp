#include "carat/registration/frame.hpp"

#include <tbb/info.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <string>
#include <utility>

#include "carat/registration/voxel_grid.hpp"
#include "carat/solver/error.hpp"
#include "parallel.hpp"

namespace carat {

Frame::Frame(PointCloud cloud) : cloud_(std::make_unique<PointCloud>(std::move(cloud))) {
  if (!cloud_->has_covariances())
    throw Error("Frame: the cloud has no covariances (run estimate_covariances first)");
  tree_ = std::make_unique<KdTree>(*cloud_);
}

Frame::Frame(PointCloud cloud, const CovarianceOptions& covariance)
    : cloud_(std::make_unique<PointCloud>(std::move(cloud))) {
  tree_ = std::make_unique<KdTree>(*cloud_);
  // Covariances do not move the points, so the tree stays valid.
  estimate_covariances(*cloud_, *tree_, covariance);
}

std::shared_ptr<const Frame> preprocess_frame(const PointCloud& raw,
                                              const PreprocessOptions& options,
                                              const std::string& name) {
  if (!(std::isfinite(options.voxel_size) && options.voxel_size > 0.0))
    throw Error(name + ": voxel size must be finite and > 0, got " +
                std::to_string(options.voxel_size));
  if (options.min_points < 4)
    throw Error(name + ": min_points must be >= 4, got " + std::to_string(options.min_points));
  if (static_cast<int>(raw.size()) < options.min_points) {
    throw Error(name + ": only " + std::to_string(raw.size()) + " points (at least " +
                std::to_string(options.min_points) + " are needed)");
  }
  PointCloud cloud = voxel_downsample(raw, options.voxel_size);
  if (static_cast<int>(cloud.size()) < options.min_points) {
    char voxel[32];
    std::snprintf(voxel, sizeof(voxel), "%g", options.voxel_size);
    throw Error(name + ": only " + std::to_string(cloud.size()) + " points after " + voxel +
                " m downsampling (at least " + std::to_string(options.min_points) + " are needed)");
  }
  CovarianceOptions covariance;
  covariance.neighbors = options.covariance_neighbors;
  covariance.num_threads = options.num_threads;
  return std::make_shared<const Frame>(std::move(cloud), covariance);
}

std::vector<std::shared_ptr<const Frame>> preprocess_frames(
    std::size_t count, const std::function<PointCloud(std::size_t)>& load,
    const std::function<std::string(std::size_t)>& name, const PreprocessOptions& options,
    int num_threads, const std::function<void(std::size_t, std::size_t)>& progress) {
  std::vector<std::shared_ptr<const Frame>> frames(count);
  PreprocessOptions single = options;
  single.num_threads = 1;  // the parallelism is over scans
  std::atomic<std::size_t> done{0};
  tbb::task_arena arena(std::clamp(num_threads, 1, tbb::info::default_concurrency()));
  arena.execute([&] {
    internal::parallel_for_each_index(count, [&](std::size_t k) {
      frames[k] = preprocess_frame(load(k), single, name(k));
      if (progress) progress(done.fetch_add(1) + 1, count);
    });
  });
  return frames;
}

}  // namespace carat
