#pragma once

// The per-frame error picture of `carat demo`: every trajectory's position error against the
// reference along the drive, after the ATE's alignment, on a log scale.

#include <Eigen/Geometry>
#include <span>
#include <string>
#include <vector>

namespace carat::cli {

/// Errors below this (metres; zero included) are drawn at it on the error plot's log axis.
inline constexpr double kErrorPlotFloor = 1e-6;

/// Per frame k, |t_reference_k - t_k| in metres, t_k the position of `estimate`'s pose k after
/// compute_ate()'s rigid alignment (T_reference_estimate): their RMS is the ATE's rmse. Throws
/// carat::Error as compute_ate() does (length mismatch, under 3 poses, non-finite poses).
std::vector<double> aligned_position_errors(std::span<const Eigen::Isometry3d> estimate,
                                            std::span<const Eigen::Isometry3d> reference);

/// One line of the error plot: per-frame errors (metres), colour, legend label, dashed or not.
struct FrameErrorLine {
  std::vector<double> errors;  ///< per frame, metres (e.g. from aligned_position_errors())
  std::string colour;          ///< SVG colour
  std::string label;           ///< legend text
  bool dashed = false;         ///< dashed line (for the initial guess)
};

/// Log-scale line plot of per-frame errors against the frame index, one line per entry with a
/// legend and a gridline per decade; errors up to kErrorPlotFloor (zero too) drawn at it,
/// non-finite ones left out, and lines drawn alike (within 0.01 decade at every frame) nested
/// from 6 px down to 1.5 px wide in their order, all stated under the plot.
std::string frame_errors_svg(const std::string& title, std::span<const FrameErrorLine> lines);

}  // namespace carat::cli
