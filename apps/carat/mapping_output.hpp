#pragma once

// Files that `carat demo` and `carat map` write: trajectories (KITTI and TUM) and SVG pictures.

#include <Eigen/Geometry>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "mapping_methods.hpp"

namespace carat::cli {

/// Writes DIR/<name>_kitti.txt and DIR/<name>_tum.txt (stamp = frame index); returns the paths.
std::vector<std::filesystem::path> write_trajectory_pair(const std::filesystem::path& dir,
                                                         const std::string& name,
                                                         std::span<const Eigen::Isometry3d> poses);

/// Writes the pictures: trajectories before (initial vs reference) and after (every method vs
/// reference); with a reference of 3 poses or more, frame_errors.svg: every method's and the
/// initial guess's per-frame position error after the ATE's alignment (log scale); and the dense
/// graph at `graph_method`'s result with factors coloured by its per-factor error. Returns the
/// paths written.
std::vector<std::filesystem::path> write_mapping_pictures(
    const std::filesystem::path& dir, std::span<const Eigen::Isometry3d> reference,
    std::span<const Eigen::Isometry3d> initial, const std::vector<MethodResult>& results,
    std::span<const FramePair> pairs, const MethodResult* graph_method);

}  // namespace carat::cli
