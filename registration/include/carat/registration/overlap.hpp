#pragma once

/// Overlap between two scans: the fraction of source points that land in a voxel occupied by
/// the target under a relative pose.

#include <Eigen/Geometry>
#include <array>
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
  /// How many of the points source.points[0], [stride], [2 stride], ... (stride 0 taken as 1)
  /// map by T_target_source into an occupied voxel: occupied(T_target_source * source.point(i))
  /// summed (the bitmap lookup inlined into the loop).
  std::size_t count_occupied(const PointCloud& source, const Eigen::Isometry3d& T_target_source,
                             std::size_t stride) const;
  /// Number of occupied voxels.
  std::size_t size() const { return keys_.size(); }
  /// Voxel edge, metres.
  double voxel_size() const { return voxel_size_; }

 private:
  double voxel_size_;
  double inverse_size_;              // 1 / voxel_size_
  std::vector<std::uint64_t> keys_;  // sorted, unique
  // The occupied voxels as one bit each over their bounding box (when the box is at most 256
  // voxels per occupied one), else as keys_ by open addressing (linear probing, ~0 when empty).
  std::array<std::int64_t, 3> box_begin_{};  // grid coordinates of the box's first voxel
  std::array<std::int64_t, 3> box_size_{};   // voxels along each axis (0: no bitmap)
  std::vector<std::uint64_t> bits_;          // bit ((x * size_y) + y) * size_z + z of the box
  std::vector<std::uint64_t> table_;
  int shift_ = 64;  // a key's home slot: (key * multiplier) >> shift_
};

/// Fraction in [0, 1] of the source points (every `stride`-th, >= 1) whose voxel is occupied in
/// `target` after mapping by T_target_source; 0 for an empty source.
double overlap_fraction(const VoxelOccupancy& target, const PointCloud& source,
                        const Eigen::Isometry3d& T_target_source, int stride = 1);

}  // namespace carat
