#pragma once

/// PCD and PLY point-cloud files (positions only): readers for PCD ascii / binary and PLY
/// ascii / binary_little_endian, writers for both (atomic: temporary file, then rename).

#include <filesystem>
#include <string>
#include <string_view>

#include "carat/registration/io/kitti_io.hpp"
#include "carat/registration/point_cloud.hpp"

namespace carat {

/// Reads x, y, z of a PCD file (DATA ascii or binary; other fields are skipped) from a regular
/// file, in bounded chunks. Every header number is checked before it becomes a size or an
/// offset. Throws carat::Error naming the file for a missing, empty or non-regular file, a
/// malformed header (unknown or repeated keys, counts that are not numbers or overflow, WIDTH x
/// HEIGHT unequal to POINTS, FIELDS / SIZE / TYPE / COUNT of different lengths, a record over
/// 1 MiB), missing or repeated x/y/z fields, an unsupported type, DATA binary_compressed, more
/// than options.max_points points, truncated data or (unless dropped) a non-finite point.
PointCloud read_pcd(const std::filesystem::path& path, const ReadOptions& options = {});

/// Parses the bytes of a PCD file held in memory; `name` is used in messages.
PointCloud parse_pcd(std::string_view bytes, const std::string& name,
                     const ReadOptions& options = {});

/// Reads the x, y, z properties of the vertex element of a PLY file (ascii or
/// binary_little_endian) from a regular file. Errors as for read_pcd(), plus big-endian files,
/// list properties on vertices and elements before the vertices.
PointCloud read_ply(const std::filesystem::path& path, const ReadOptions& options = {});

/// Parses the bytes of a PLY file held in memory; `name` is used in messages.
PointCloud parse_ply(std::string_view bytes, const std::string& name,
                     const ReadOptions& options = {});

/// Writes positions as PCD (binary unless ascii is true), float32 x y z.
void write_pcd(const std::filesystem::path& path, const PointCloud& cloud, bool ascii = false);

/// Writes positions as PLY (binary_little_endian unless ascii is true), float32 x y z.
void write_ply(const std::filesystem::path& path, const PointCloud& cloud, bool ascii = false);

/// Reads a cloud by the file's extension: .pcd (read_pcd), .ply (read_ply) or .bin
/// (read_kitti_bin with `kitti_format`, which the other formats ignore). Any other extension
/// (they are case-sensitive) throws carat::Error "PATH: unsupported file type 'EXT' (expected
/// .pcd, .ply or .bin)"; otherwise throws as the reader does.
PointCloud read_point_cloud(const std::filesystem::path& path,
                            KittiFormat kitti_format = KittiFormat::kXyzi,
                            const ReadOptions& options = {});

}  // namespace carat
