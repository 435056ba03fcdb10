#pragma once

// `carat map`'s trajectories: the reference (--poses) and the start (--initial, or the reference
// perturbed), one pose per scan in scan order, relative to the start's first pose.

#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

#include "carat/registration/io/scan_folder.hpp"
#include "carat/registration/io/trajectory_io.hpp"

namespace carat::cli {

/// The command line's trajectory settings.
struct MapTrajectoryArgs {
  std::string frames;                  // --frames, for messages
  std::string poses;                   // --poses (may be empty)
  std::string poses_format = "kitti";  // --poses-format
  std::string initial;                 // --initial (may be empty)
  std::string initial_format;          // --initial-format (empty: --poses-format)
  double perturb_m = 0.0;              // --perturb-m
  double perturb_deg = 0.0;            // --perturb-deg
  std::uint64_t seed = 1;              // --seed
};

/// The trajectories of the run: the reference (--poses) and the start (--initial, else the
/// reference), one pose per scan in scan order, and the poses relative to the start's first.
struct MapTrajectories {
  Trajectory reference;                                    // empty without --poses
  Trajectory start;                                        // --initial, else the reference
  TrajectoryFormat out_format = TrajectoryFormat::kKitti;  // of --out: the start's format
  Eigen::Isometry3d T_world_anchor = Eigen::Isometry3d::Identity();  // the start's first pose
  std::vector<Eigen::Isometry3d> reference_poses;                    // relative to the anchor
  std::vector<Eigen::Isometry3d> T_world_initial;  // relative to the anchor (perturbed, maybe)
};

/// Reads --poses and --initial for `files` (throws carat::Error naming the option for a pose
/// count that is not the frame count) and perturbs the reference when there is no --initial.
MapTrajectories read_map_trajectories(const MapTrajectoryArgs& args,
                                      const std::vector<ScanFile>& files);

}  // namespace carat::cli
