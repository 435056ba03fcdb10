#pragma once

/// Overlap between two scans: the fraction of source points that land in a voxel occupied by
/// the target under a relative pose.

#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "carat/registration/point_cloud.hpp"

namespace carat {

/// The set of voxels (edge voxel_size) occupied by a cloud, in the cloud's own frame.
class VoxelOccupancy {
 public:
  /// Records the voxel of every point. Throws carat::Error for a voxel size that is not finite
  /// and > 0, or a coordinate too large for the grid.
  VoxelOccupancy(const PointCloud& cloud, double voxel_size);
  /// Whether the voxel containing p (same frame as the cloud) holds a point.
  bool occupied(const Eigen::Vector3d& p) const;
  /// Number of occupied voxels.
  std::size_t size() const { return keys_.size(); }
  /// Voxel edge, metres.
  double voxel_size() const { return voxel_size_; }

 private:
  double voxel_size_;
  std::vector<std::uint64_t> keys_;  // sorted, unique
};

/// Fraction in [0, 1] of the source points (every `stride`-th, >= 1) whose voxel is occupied in
/// `target` after mapping by T_target_source; 0 for an empty source.
double overlap_fraction(const VoxelOccupancy& target, const PointCloud& source,
                        const Eigen::Isometry3d& T_target_source, int stride = 1);

}  // namespace carat
