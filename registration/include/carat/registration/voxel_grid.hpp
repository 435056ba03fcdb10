#pragma once

/// Voxel-grid downsampling: one point (the centroid) per occupied voxel.

#include "carat/registration/point_cloud.hpp"

namespace carat {

/// Centroids of the occupied voxels of edge `voxel_size` (metres), ordered by voxel
/// coordinates (deterministic). Covariances are not carried over. Throws carat::Error for a
/// voxel size that is not finite and > 0, or coordinates too large for the voxel grid (naming
/// the first such point). num_threads is clamped to [1, cores]; the result does not depend on it.
PointCloud voxel_downsample(const PointCloud& cloud, double voxel_size, int num_threads = 1);

}  // namespace carat
