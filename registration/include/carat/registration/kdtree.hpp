#pragma once

/// k-nearest-neighbour search over a point cloud's positions: a k-d tree split at the median of
/// each cell's widest axis, its leaves' positions stored contiguously.

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "carat/registration/point_cloud.hpp"

namespace carat {

/// A k-d tree over the positions of a cloud; the cloud must outlive the tree and not change.
class KdTree {
 public:
  /// Builds the tree (up to 56 points a leaf). An empty cloud gives a tree that finds nothing.
  explicit KdTree(const PointCloud& cloud);
  ~KdTree();
  KdTree(const KdTree&) = delete;
  KdTree& operator=(const KdTree&) = delete;

  /// Up to k nearest points of `query`: indices and squared distances, nearest first.
  /// Returns how many were found (fewer than k only when the cloud is smaller than k).
  int knn(const Eigen::Vector3f& query, int k, std::uint32_t* indices,
          float* squared_distances) const;

  /// What knn() finds for each query, in order: query q's points in indices[q * k, q * k + k)
  /// and squared_distances alike, found[q] of them (nearest first). The same answers as knn(),
  /// ties included; each search is bounded by the one before (the k points the previous query
  /// found bound the reach of the next), so runs of nearby queries (a scan's own points in
  /// voxel order) are answered faster than one at a time.
  void knn(std::span<const Eigen::Vector3f> queries, int k, std::uint32_t* indices,
           float* squared_distances, int* found) const;

  /// The nearest point: its index and squared distance; false for an empty cloud.
  bool nearest(const Eigen::Vector3f& query, std::uint32_t* index, float* squared_distance) const;

  /// The nearest point within max_squared_distance (inclusive) of `query`; false if there is
  /// none. The same answer as nearest() followed by the distance test (up to rounding when the
  /// nearest distance is within an ulp of the bound), but branches beyond the bound are pruned.
  bool nearest_within(const Eigen::Vector3f& query, float max_squared_distance,
                      std::uint32_t* index, float* squared_distance) const;

  /// What nearest_within() finds for each query, in order: indices[k] (kNotFound when no point
  /// is within the bound) and squared_distances[k] (infinity then). The distances are exactly
  /// nearest_within()'s; among points at the very same distance another one may be returned.
  /// Each search starts in the cell where the one before ended, so runs of nearby queries (a scan
  /// in voxel order) are answered faster than one at a time.
  void nearest_within(std::span<const Eigen::Vector3f> queries, float max_squared_distance,
                      std::uint32_t* indices, float* squared_distances) const;

  /// The index nearest_within() gives a query with no point within the bound.
  static constexpr std::uint32_t kNotFound = ~std::uint32_t{0};

  /// Bytes the tree holds (its nodes and its index array; the cloud is not counted).
  std::size_t memory_bytes() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace carat
