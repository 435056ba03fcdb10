#include "carat/registration/covariance.hpp"

#include <tbb/info.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <string>
#include <vector>

#include "carat/base/error.hpp"

namespace carat {

void estimate_covariances(PointCloud& cloud, const KdTree& tree, const CovarianceOptions& options) {
  if (options.neighbors < 4)
    throw Error("estimate_covariances: neighbors must be >= 4, got " +
                std::to_string(options.neighbors));
  if (cloud.size() < 4) {
    throw Error("estimate_covariances: a cloud of " + std::to_string(cloud.size()) +
                " points is too small (at least 4 are needed)");
  }
  const int k = static_cast<int>(
      std::min<std::size_t>(static_cast<std::size_t>(options.neighbors), cloud.size()));
  cloud.covariances.resize(cloud.size());
  const auto work = [&](const tbb::blocked_range<std::size_t>& range) {
    // The range's points searched as one run (a voxel-ordered scan's neighbours follow each
    // other): the same neighbours as one search at a time.
    const std::size_t count = range.size();
    std::vector<std::uint32_t> indices(count * static_cast<std::size_t>(k));
    std::vector<float> distances(count * static_cast<std::size_t>(k));
    std::vector<int> founds(count);
    tree.knn(std::span(cloud.points.data() + range.begin(), count), k, indices.data(),
             distances.data(), founds.data());
    for (std::size_t i = range.begin(); i != range.end(); ++i) {
      const std::size_t at = i - range.begin();
      const int found = founds[at];
      const std::uint32_t* neighbours = indices.data() + at * static_cast<std::size_t>(k);
      Eigen::Vector3d mean = Eigen::Vector3d::Zero();
      Eigen::Matrix3d second = Eigen::Matrix3d::Zero();
      for (int n = 0; n < found; ++n) {
        const Eigen::Vector3d p = cloud.point(neighbours[n]);
        mean += p;
        second += p * p.transpose();
      }
      mean /= found;
      const Eigen::Matrix3d C = second / found - mean * mean.transpose();
      // V diag(1e-3, 1, 1) V^T = I - (1 - 1e-3) n n^T with n the eigenvector of the smallest
      // eigenvalue (the normal): only n is needed, from the closed-form 3 x 3 solver.
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
      eig.computeDirect(C);
      const Eigen::Vector3d n = eig.eigenvectors().col(0).normalized();
      cloud.set_covariance(i, Eigen::Matrix3d::Identity() - (1.0 - 1e-3) * n * n.transpose());
    }
  };
  tbb::task_arena arena(std::clamp(options.num_threads, 1, tbb::info::default_concurrency()));
  arena.execute(
      [&] { tbb::parallel_for(tbb::blocked_range<std::size_t>(0, cloud.size(), 256), work); });
}

}  // namespace carat
