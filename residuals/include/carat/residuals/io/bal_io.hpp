#pragma once

/// The BAL text format ("Bundle Adjustment in the Large"): a header
///   num_cameras num_points num_observations
/// then num_observations records `camera_index point_index x y`, then 9 numbers per camera
/// (snavely_camera.hpp) and 3 per point, all separated by any whitespace (line breaks included).

#include <filesystem>
#include <ostream>
#include <string>
#include <string_view>

#include "carat/residuals/bal_problem.hpp"

namespace carat {

/// Reads a BAL file (a regular file, or a FIFO or device such as `<(bzcat file.bz2)`). Throws
/// carat::Error "PATH:LINE: problem" for: a missing file, a directory or socket; a header count
/// that is not an integer in [1, 2^31 - 1]; counts that need more bytes than the file holds
/// (checked before anything is allocated); a truncated file; a number that cannot be read, is out
/// of range or not finite; a camera or point index out of range; data after the last point; a
/// camera that observes no point or a point no camera observes (such a variable would leave the
/// problem singular, so the reader refuses it rather than accept it silently). Points behind
/// their cameras are accepted (see count_points_behind_cameras()).
BalProblem read_bal(const std::filesystem::path& path);

/// Parses BAL text held in memory; `name` is used in error messages (as the path is by read_bal).
BalProblem parse_bal(std::string_view text, const std::string& name);

/// Writes `problem` in BAL format atomically (a temporary file, then rename; see atomic_file.hpp)
/// with every number in its shortest form that reads back to the same double (exact round trip).
/// Throws carat::Error if the problem fails check_bal_problem() or the file cannot be written.
void write_bal(const std::filesystem::path& path, const BalProblem& problem);

/// Writes `problem` in BAL format to a stream (see the path overload).
void write_bal(std::ostream& out, const BalProblem& problem);

}  // namespace carat
