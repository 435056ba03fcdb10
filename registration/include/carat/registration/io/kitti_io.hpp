#pragma once

/// KITTI Velodyne scans: raw little-endian float32 records, no header.

#include <cstddef>
#include <filesystem>
#include <string>
#include <string_view>

#include "carat/registration/point_cloud.hpp"

namespace carat {

/// Record layout of a KITTI .bin file.
enum class KittiFormat {
  kXyzi,  ///< x y z intensity: 16 bytes per point (the original KITTI layout)
  kXyz,   ///< x y z: 12 bytes per point (intensity dropped, as in ../shared/data)
};

/// Name of a record layout: "xyzi" or "xyz".
const char* to_string(KittiFormat format);
/// Parses "xyzi" or "xyz"; throws carat::Error listing them otherwise.
KittiFormat parse_kitti_format(std::string_view name);

/// How point-cloud readers treat non-finite points, and how large a cloud they accept.
struct ReadOptions {
  bool drop_non_finite = false;  ///< drop NaN/Inf points instead of failing
  /// Most points one file may announce or hold (100 M points: 1.2 GB as float x y z). A larger
  /// count is refused before anything is allocated.
  std::size_t max_points = 100'000'000;
};

/// Reads a KITTI .bin scan from a regular file, in bounded chunks. Throws carat::Error naming
/// the file for a missing, empty or non-regular file, a size that is not a whole number of
/// records, more than options.max_points points, or (unless dropped) a non-finite point.
PointCloud read_kitti_bin(const std::filesystem::path& path, KittiFormat format,
                          const ReadOptions& options = {});

/// Parses the bytes of a KITTI .bin scan held in memory; `name` is used in messages. Errors as
/// for read_kitti_bin().
PointCloud parse_kitti_bin(std::string_view bytes, KittiFormat format, const std::string& name,
                           const ReadOptions& options = {});

/// Writes a KITTI .bin scan (little-endian float32 records; intensity 0 for kXyzi) atomically.
/// An empty cloud gives an empty file (which read_kitti_bin rejects). Throws carat::Error naming
/// the file for a non-finite point or a failed write.
void write_kitti_bin(const std::filesystem::path& path, const PointCloud& cloud,
                     KittiFormat format);

}  // namespace carat
