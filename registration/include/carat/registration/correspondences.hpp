#pragma once

/// Nearest-neighbour correspondences between two clouds under a relative pose.

#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "carat/registration/kdtree.hpp"
#include "carat/registration/point_cloud.hpp"
#include "carat/residuals/gicp_block.hpp"

namespace carat {

/// For every source point, its nearest target point after mapping by T_target_source, kept when
/// within max_distance (metres): the pairs (target index, source index) in source order.
/// `target_tree` indexes `target`. `previous` (optional) are the pairs of an earlier search of
/// the same clouds at any pose: a source point's earlier partner bounds its search, which prunes
/// the tree sooner and changes no pair (up to exact ties). Parallel, deterministic.
std::vector<std::array<std::uint32_t, 2>> find_nearest_pairs(
    const PointCloud& target, const KdTree& target_tree, const PointCloud& source,
    const Eigen::Isometry3d& T_target_source, double max_distance,
    std::span<const std::array<std::uint32_t, 2>> previous = {});

/// For every source point, its nearest target point after mapping by T_target_source, kept when
/// closer than max_distance (metres); in source order, with both points' covariances. Both
/// clouds need covariances; `target_tree` indexes `target`. Parallel, deterministic.
std::vector<GicpCorrespondence> find_correspondences(const PointCloud& target,
                                                     const KdTree& target_tree,
                                                     const PointCloud& source,
                                                     const Eigen::Isometry3d& T_target_source,
                                                     double max_distance);

}  // namespace carat
