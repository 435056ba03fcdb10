#pragma once

/// Per-point covariances from k nearest neighbours, regularized to a plane (GICP): the
/// eigenvalues of each neighbourhood covariance are replaced by (1e-3, 1, 1).

#include "carat/registration/kdtree.hpp"
#include "carat/registration/point_cloud.hpp"

namespace carat {

/// Settings of estimate_covariances().
struct CovarianceOptions {
  int neighbors = 10;   ///< k, including the point itself (>= 4)
  int num_threads = 1;  ///< threads (>= 1)
};

/// Fills cloud.covariances. Every point uses its k nearest neighbours; a cloud with fewer than
/// k points uses all of its points for every neighbourhood. Throws carat::Error for fewer than
/// 4 points or k < 4.
void estimate_covariances(PointCloud& cloud, const KdTree& tree,
                          const CovarianceOptions& options = {});

}  // namespace carat
