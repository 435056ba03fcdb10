#include "carat/registration/frame.hpp"

#include <tbb/info.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <string>
#include <utility>

#include "carat/base/error.hpp"
#include "carat/registration/voxel_grid.hpp"
#include "parallel.hpp"

namespace carat {

Frame::Frame(PointCloud cloud) : cloud_(std::make_unique<PointCloud>(std::move(cloud))) {
  if (!cloud_->has_covariances())
    throw Error("Frame: the cloud has no covariances (run estimate_covariances first)");
  tree_ = std::make_unique<KdTree>(*cloud_);
  measure_constraint();
}

Frame::Frame(PointCloud cloud, const CovarianceOptions& covariance)
    : cloud_(std::make_unique<PointCloud>(std::move(cloud))) {
  tree_ = std::make_unique<KdTree>(*cloud_);
  // Covariances do not move the points, so the tree stays valid.
  estimate_covariances(*cloud_, *tree_, covariance);
  measure_constraint();
}

std::size_t Frame::memory_bytes() const {
  return sizeof(Frame) + sizeof(PointCloud) + cloud_->memory_bytes() + tree_->memory_bytes() +
         name_.capacity();
}

void Frame::measure_constraint() {
  const PointCloud& cloud = *cloud_;
  // Rotations are measured in metres at the median radius, and no point's lever arm counts for
  // more than 10 median radii: a few outliers far away cannot hide how the rest of the scan
  // constrains the pose.
  std::vector<double> radii(cloud.size());
  for (std::size_t k = 0; k < cloud.size(); ++k) radii[k] = cloud.point(k).norm();
  const std::size_t middle = radii.size() / 2;
  std::nth_element(radii.begin(), radii.begin() + static_cast<std::ptrdiff_t>(middle), radii.end());
  const double radius = std::max(radii.empty() ? 0.0 : radii[middle], 1e-6);
  // H = sum J^T C^-1 J with J = [-[p]x / radius, I].
  Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
  for (std::size_t k = 0; k < cloud.size(); ++k) {
    const Eigen::Matrix3d C = cloud.covariance(k);
    const Eigen::LDLT<Eigen::Matrix3d> ldlt(C);
    if (ldlt.info() != Eigen::Success) continue;
    const Eigen::Matrix3d info = ldlt.solve(Eigen::Matrix3d::Identity());
    if (!info.allFinite()) continue;
    Eigen::Matrix<double, 3, 6> J;
    Eigen::Vector3d p = cloud.point(k) / radius;
    if (p.norm() > 10.0) p *= 10.0 / p.norm();
    J.leftCols<3>() << 0.0, p.z(), -p.y(), -p.z(), 0.0, p.x(), p.y(), -p.x(), 0.0;
    J.rightCols<3>().setIdentity();
    H.noalias() += J.transpose() * info * J;
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> eigen(H, Eigen::EigenvaluesOnly);
  const double largest = eigen.eigenvalues().maxCoeff();
  constrained_dof_ = 0;
  min_eigenvalue_ratio_ = 0.0;
  if (!(largest > 0.0) || !std::isfinite(largest)) return;
  min_eigenvalue_ratio_ = std::max(0.0, eigen.eigenvalues().minCoeff() / largest);
  for (int k = 0; k < 6; ++k) {
    if (eigen.eigenvalues()[k] > 5e-3 * largest) ++constrained_dof_;
  }
}

PointCloud downsample_frame_points(const PointCloud& raw, const PreprocessOptions& options,
                                   const std::string& name) {
  if (!(std::isfinite(options.voxel_size) && options.voxel_size > 0.0))
    throw Error(name + ": voxel size must be finite and > 0, got " +
                std::to_string(options.voxel_size));
  if (options.min_points < 4)
    throw Error(name + ": min_points must be >= 4, got " + std::to_string(options.min_points));
  PointCloud cloud;
  try {
    cloud = voxel_downsample(raw, options.voxel_size, options.num_threads);
  } catch (const Error& e) {
    throw Error(name + ": " + e.what());
  }
  if (cloud.size() < static_cast<std::size_t>(options.min_points)) {
    throw Error(name + ": only " + std::to_string(cloud.size()) +
                " points after downsampling (at least " + std::to_string(options.min_points) +
                " are needed)");
  }
  return cloud;
}

std::shared_ptr<const Frame> preprocess_frame(const PointCloud& raw,
                                              const PreprocessOptions& options,
                                              const std::string& name) {
  PointCloud cloud = downsample_frame_points(raw, options, name);
  CovarianceOptions covariance;
  covariance.neighbors = options.covariance_neighbors;
  covariance.num_threads = options.num_threads;
  auto frame = std::make_shared<Frame>(std::move(cloud), covariance);
  frame->set_name(name);
  return frame;
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
