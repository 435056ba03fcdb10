#pragma once

/// A point cloud: positions and, once estimated, per-point covariances. Stored in float32 to
/// keep thousands of frames in memory: 12 bytes per point for positions, 24 more with
/// covariances (the 6 unique entries xx, xy, xz, yy, yz, zz), 36 bytes in all.

#include <Eigen/Core>
#include <cstddef>
#include <vector>

namespace carat {

/// Positions (metres, in the cloud's own frame) and optional covariances.
struct PointCloud {
  std::vector<Eigen::Vector3f> points;                  ///< positions
  std::vector<Eigen::Matrix<float, 6, 1>> covariances;  ///< empty, or one per point

  /// Number of points.
  std::size_t size() const { return points.size(); }
  /// True when every point has a covariance.
  bool has_covariances() const { return !points.empty() && covariances.size() == points.size(); }
  /// Position i in double precision.
  Eigen::Vector3d point(std::size_t i) const { return points[i].cast<double>(); }
  /// Covariance i as a symmetric 3x3 matrix in double precision.
  Eigen::Matrix3d covariance(std::size_t i) const;
  /// Stores covariance i from a symmetric 3x3 matrix.
  void set_covariance(std::size_t i, const Eigen::Matrix3d& C);
  /// Bytes held by the cloud's arrays.
  std::size_t memory_bytes() const;
};

}  // namespace carat
