#pragma once

/// PCD and PLY point-cloud files (positions only): readers for PCD ascii / binary and PLY
/// ascii / binary_little_endian, writers for both (atomic: temporary file, then rename).

#include <filesystem>

#include "carat/registration/kitti_io.hpp"
#include "carat/registration/point_cloud.hpp"

namespace carat {

/// Reads x, y, z of a PCD file (DATA ascii or binary; other fields are skipped). Throws
/// carat::Error naming the file for a missing or empty file, a malformed header, missing x/y/z
/// fields, an unsupported type, DATA binary_compressed, truncated data or (unless dropped) a
/// non-finite point.
PointCloud read_pcd(const std::filesystem::path& path, const ReadOptions& options = {});

/// Reads the x, y, z properties of the vertex element of a PLY file (ascii or
/// binary_little_endian). Errors as for read_pcd(), plus big-endian files and list properties
/// on vertices.
PointCloud read_ply(const std::filesystem::path& path, const ReadOptions& options = {});

/// Writes positions as PCD (binary unless ascii is true), float32 x y z.
void write_pcd(const std::filesystem::path& path, const PointCloud& cloud, bool ascii = false);

/// Writes positions as PLY (binary_little_endian unless ascii is true), float32 x y z.
void write_ply(const std::filesystem::path& path, const PointCloud& cloud, bool ascii = false);

/// Reads .pcd, .ply or .bin (KITTI, with `kitti_format`) by the file's extension.
PointCloud read_point_cloud(const std::filesystem::path& path,
                            KittiFormat kitti_format = KittiFormat::kXyzi,
                            const ReadOptions& options = {});

}  // namespace carat
