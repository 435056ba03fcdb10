#pragma once

/// Nearest-neighbour correspondences between two clouds under a relative pose.

#include <Eigen/Geometry>
#include <vector>

#include "carat/registration/kdtree.hpp"
#include "carat/registration/point_cloud.hpp"
#include "carat/residuals/gicp_block.hpp"

namespace carat {

/// For every source point, its nearest target point after mapping by T_target_source, kept when
/// closer than max_distance (metres); in source order, with both points' covariances. Both
/// clouds need covariances; `target_tree` indexes `target`. Parallel, deterministic.
std::vector<GicpCorrespondence> find_correspondences(const PointCloud& target,
                                                     const KdTree& target_tree,
                                                     const PointCloud& source,
                                                     const Eigen::Isometry3d& T_target_source,
                                                     double max_distance);

}  // namespace carat
