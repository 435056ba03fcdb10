#pragma once

/// A folder of scans, as `carat map` reads it: DIR/*.bin|*.pcd|*.ply (KITTI velodyne layout:
/// .bin is x y z intensity), or DIR/<frame>/points.bin (gtsam_points dumps: x y z), in natural
/// name order (2.bin before 10.bin); hidden names are skipped. Poses pair with the scans by line
/// (KITTI, TUM) or by vertex id (graph.txt: scan 000003 takes v3).

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "carat/registration/io/kitti_io.hpp"
#include "carat/registration/io/trajectory_io.hpp"
#include "carat/registration/point_cloud.hpp"

namespace carat {

/// One scan of a folder and how to read it.
struct ScanFile {
  std::filesystem::path path;                   ///< the file (DIR/x.bin or DIR/<frame>/points.bin)
  std::string name;                             ///< the frame's name: file stem or folder name
  KittiFormat bin_format = KittiFormat::kXyzi;  ///< record layout when the file is .bin
};

/// How .bin records of a scan folder are laid out.
enum class BinLayout {
  kAuto,  ///< x y z for <frame>/points.bin, x y z intensity for DIR/*.bin
  kXyz,   ///< 12 bytes per point everywhere
  kXyzi,  ///< 16 bytes per point everywhere
};

/// Name of a layout: "auto", "xyz" or "xyzi".
const char* to_string(BinLayout layout);
/// Parses "auto", "xyz" or "xyzi"; throws carat::Error listing them otherwise.
BinLayout parse_bin_layout(std::string_view name);

/// Whether `name` is a scan file name: it ends in .bin, .pcd or .ply (lower case).
bool is_frame_file_name(std::string_view name);

/// Whether `name` looks like a scan file name in any case or dress: .BIN, .Pcd, "x.bin~",
/// "x.bin " or a frame extension before another one ("x.bin.gz").
bool looks_like_frame_name(std::string_view name);

/// The scans of `dir` in natural name order; other files and hidden names (a leading '.') are
/// skipped. Throws carat::Error naming the path when `dir` is not a folder, holds no scans, mixes
/// the two layouts, or holds an entry that skipping would turn into a silent shift of every later
/// frame's pose: a scan name (*.bin, *.pcd, *.ply) that is not a regular file, a directory named
/// like a scan file, a file named like one in another case or dress (looks_like_frame_name()),
/// or, among <frame>/points.bin frames, a folder without points.bin.
std::vector<ScanFile> list_scan_folder(const std::filesystem::path& dir,
                                       BinLayout layout = BinLayout::kAuto);

/// Reads one scan (by its extension). Throws carat::Error as the readers do.
PointCloud read_scan(const ScanFile& scan, const ReadOptions& options = {});

/// The graph vertex id of each scan, the one rule of every reader and writer of graph poses for
/// a scan folder: the scan's name as a number (`000003` is v3, a 19-digit nanosecond stamp its
/// own id) when every name is a decimal number below 2^64 and no two are equal; otherwise the
/// scan's index in natural order (v0, v1, ...).
std::vector<std::uint64_t> scan_graph_ids(const std::vector<ScanFile>& scans);

/// The poses of `trajectory` in scan order: KITTI and TUM poses by line (the counts must be
/// equal), graph.txt poses by vertex id as scan_graph_ids() gives them: numbered scans take the
/// vertex of their number; otherwise the scans in order take the ids in increasing order. The
/// result keeps the stamps and the ids of the poses it takes. Throws carat::Error naming
/// `poses_name` and the scan for different counts or a numbered scan without its vertex.
Trajectory poses_in_scan_order(const Trajectory& trajectory, TrajectoryFormat format,
                               const std::vector<ScanFile>& scans, const std::string& poses_name);

/// Whether `a` comes before `b` in natural order: runs of digits compare as numbers.
bool natural_less(std::string_view a, std::string_view b);

}  // namespace carat
