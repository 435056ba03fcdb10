#pragma once

/// Trajectory files: KITTI odometry poses, TUM RGB-D and gtsam_points graph.txt, read strictly
/// (every error names the file and the line) and written atomically.
///
/// Every line holds one pose T_world_frame (p_world = R p_frame + t). Blank lines are skipped and
/// CRLF line endings are accepted. Numbers are read with std::from_chars (no locale); a number
/// that is not finite or out of double range is an error, as is a wrong field count or trailing
/// garbage. A KITTI rotation is accepted if |R^T R - I| (Frobenius) <= 1e-3 and det R > 0, and is
/// then re-orthonormalized; a quaternion is accepted if |norm(q) - 1| <= 1e-3, and is then
/// normalized. TUM stamps must increase strictly; graph ids must be unique decimal integers
/// (v0 ... v18446744073709551615, so that 19-digit nanosecond timestamps stay exact).

#include <Eigen/Geometry>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace carat {

/// On-disk trajectory formats.
enum class TrajectoryFormat {
  kKitti,  ///< KITTI odometry: 12 numbers per line, row-major 3x4 [R|t]; stamp = pose index
  kTum,    ///< TUM RGB-D: "stamp tx ty tz qx qy qz qw" per line; '#' comment lines allowed
  kGraph,  ///< gtsam_points graph.txt: "vN tx ty tz qx qy qz qw" per line; stamp = N
};

/// Name of a format: "kitti", "tum" or "graph".
const char* to_string(TrajectoryFormat format);
/// Parses a format name: "kitti", "tum" or "graph" (throws carat::Error listing them otherwise).
TrajectoryFormat parse_trajectory_format(std::string_view name);

/// A sequence of poses T_world_frame with one stamp each (stamps.size() == poses.size()).
struct Trajectory {
  std::vector<double> stamps;            ///< seconds (TUM), pose index (KITTI) or id (graph)
  std::vector<Eigen::Isometry3d> poses;  ///< T_world_frame of each pose
  /// Graph vertex ids, exact (a double holds integers only up to 2^53): filled by the graph
  /// reader, written by the graph writer when not empty (else the stamps are the ids).
  std::vector<std::uint64_t> ids;
};

/// Parses trajectory text; `name` (a file name) is used in error messages as "name:line: problem".
/// Throws carat::Error for any malformed line and for text without poses.
Trajectory parse_trajectory(std::string_view text, TrajectoryFormat format,
                            const std::string& name);

/// Reads a trajectory file line by line: a regular file, or a FIFO or device (e.g. `<(command)`).
/// Throws carat::Error naming it for a missing, unreadable or empty file, a directory, a line
/// longer than 64 KiB or holding a NUL byte, and as parse_trajectory() does.
Trajectory read_trajectory(const std::filesystem::path& path, TrajectoryFormat format);

/// Formats a trajectory as text that parse_trajectory() reads back to the same poses (numbers in
/// shortest round-trip form; graph ids written as "v<id>", from `ids` when it is not empty, else
/// from the stamps). Throws carat::Error for mismatched stamp, id and pose counts, non-finite
/// values, TUM stamps that do not increase, repeated graph ids, or graph stamps (without ids)
/// that are not integers in [0, 2^53].
std::string format_trajectory(const Trajectory& trajectory, TrajectoryFormat format);

/// Writes format_trajectory() atomically (temporary file, then rename); errors name the path.
void write_trajectory(const std::filesystem::path& path, const Trajectory& trajectory,
                      TrajectoryFormat format);

}  // namespace carat
