#pragma once

/// KITTI Velodyne scans: raw little-endian float32 records, no header.

#include <filesystem>

#include "carat/registration/point_cloud.hpp"

namespace carat {

/// Record layout of a KITTI .bin file.
enum class KittiFormat {
  kXyzi,  ///< x y z intensity: 16 bytes per point (the original KITTI layout)
  kXyz,   ///< x y z: 12 bytes per point (intensity dropped, as in ../shared/data)
};

/// How to treat non-finite points while reading.
struct ReadOptions {
  bool drop_non_finite = false;  ///< drop NaN/Inf points instead of failing
};

/// Reads a KITTI .bin scan. Throws carat::Error naming the file for a missing or empty file, a
/// size that is not a whole number of records, or (unless dropped) a non-finite point.
PointCloud read_kitti_bin(const std::filesystem::path& path, KittiFormat format,
                          const ReadOptions& options = {});

/// Writes a KITTI .bin scan (little-endian float32 records; intensity 0 for kXyzi) atomically.
/// An empty cloud gives an empty file (which read_kitti_bin rejects). Throws carat::Error naming
/// the file for a non-finite point or a failed write.
void write_kitti_bin(const std::filesystem::path& path, const PointCloud& cloud,
                     KittiFormat format);

}  // namespace carat
